// The pbrt-v4 parser over mutated copies of the shipped .pbrt scenes, a bounded number of them
// (fixed seed): every mutation either loads or is rejected with a SceneError that names where
// (the text's name and usually a line); nothing else is thrown and nothing crashes or hangs.
// Mutations: delete, duplicate or swap a line; replace a token by a hostile one ("nan", "1e39",
// "-1", "[", "]", "\"", "#", an unknown word, a huge integer); truncate the file.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/scene/pbrt/scene_loader.h"

namespace render {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
}

std::string join(const std::vector<std::string>& lines) {
    std::string out;
    for (const std::string& l : lines) out += l + "\n";
    return out;
}

std::string mutate(const std::string& text, std::mt19937& rng) {
    std::vector<std::string> lines = lines_of(text);
    auto pick = [&](size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(rng); };
    static const char* kHostile[] = {"nan",
                                     "1e39",
                                     "-1",
                                     "[",
                                     "]",
                                     "\"",
                                     "#",
                                     "Bogus",
                                     "\"\"",
                                     "99999999999",
                                     "0",
                                     "-0",
                                     "\"float radius\"",
                                     "\"integer indices\" [ 0 ]"};
    switch (pick(5)) {
        case 0:
            lines.erase(lines.begin() + long(pick(lines.size())));
            break;
        case 1: {
            const size_t i = pick(lines.size());
            lines.insert(lines.begin() + long(i), lines[i]);
            break;
        }
        case 2:
            std::swap(lines[pick(lines.size())], lines[pick(lines.size())]);
            break;
        case 3: {
            // Replace one whitespace-separated token of a line.
            std::string& line = lines[pick(lines.size())];
            std::vector<size_t> starts;
            for (size_t i = 0; i < line.size(); ++i)
                if (line[i] != ' ' && (i == 0 || line[i - 1] == ' ')) starts.push_back(i);
            if (starts.empty()) break;
            const size_t s = starts[pick(starts.size())];
            size_t e = line.find(' ', s);
            if (e == std::string::npos) e = line.size();
            line = line.substr(0, s) + kHostile[pick(sizeof(kHostile) / sizeof(kHostile[0]))] +
                   line.substr(e);
            break;
        }
        default:
            return text.substr(0, pick(text.size()));
    }
    return join(lines);
}

void fuzz(const std::string& scene, int count, uint32_t seed) {
    const fs::path file = fs::path(RENDER_SOURCE_DIR) / "scenes/bitterli-pbrt" / scene;
    std::ifstream in(file, std::ios::binary);
    std::ostringstream original;
    original << in.rdbuf();
    std::mt19937 rng(seed);
    int loaded = 0, rejected = 0;
    for (int i = 0; i < count; ++i) {
        const std::string text = mutate(original.str(), rng);
        try {
            pbrt::load_scene_from_string(text, file.parent_path());
            ++loaded;
        } catch (const SceneError& e) {
            ++rejected;
            const std::string message = e.what();
            // Located: the text's name ("<string>:line: ...", or "<string>: ..." for the whole
            // file) or a mesh file's path.
            EXPECT_TRUE(message.rfind("<string>", 0) == 0 ||
                        message.find(".ply") != std::string::npos)
                << "unlocated error for mutation " << i << ": " << message;
        } catch (const std::exception& e) {
            ADD_FAILURE() << "mutation " << i << " threw a non-SceneError: " << e.what() << "\n"
                          << text;
        }
    }
    // Both outcomes occur, so the mutations do reach the parser's checks.
    EXPECT_GT(loaded, 0) << scene;
    EXPECT_GT(rejected, 0) << scene;
}

TEST(PbrtFuzz, CornellBox) {
    fuzz("cornell-box/scene-v4.pbrt", 1000, 1);
}
TEST(PbrtFuzz, WaterCaustic) {
    fuzz("water-caustic/scene-v4.pbrt", 20, 2);
}
TEST(PbrtFuzz, Coffee) {
    fuzz("coffee/scene-v4.pbrt", 6, 3);
}

}  // namespace
}  // namespace render
