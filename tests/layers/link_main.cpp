// The program of the layers_link_LAYER targets (tests/CMakeLists.txt): it does nothing; linking
// it with the whole of one core layer's library is the check.
int main() {
    return 0;
}
