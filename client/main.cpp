// `client`: the command line of the render service.
//
//   client [--server HOST:PORT] [--token T] [--tls-ca FILE [--tls-server-name NAME]] COMMAND ...
//
// The commands and the global options are tables (client/commands.h); this file parses the
// global options, finds the command and reports its failure.

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "client/commands.h"
#include "service/process_setup.h"

using namespace render::service;

int main(int argc, char** argv) {
    render::service::prepare_grpc_process();
    GlobalOptions global;
    if (const char* env = std::getenv("RENDER_SERVER"); env && *env) global.server = env;
    const Arguments all(argv + std::min(argc, 1), argv + argc);
    // Global options come before the command; everything from the command on is its own.
    size_t first = 0;
    try {
        first = global_parser(global).parse_leading(all);
    } catch (const render::UsageError& e) {
        usage_error(e.what());
    }
    if (first == all.size()) usage_error("no command given");
    if (global.server.empty()) global.server = "127.0.0.1:50051";
    const Command* command = find_command(all[first]);
    if (!command) usage_error("unknown command " + all[first]);
    const Arguments args(all.begin() + std::ptrdiff_t(first) + 1, all.end());
    try {
        Connection c;
        if (command->remote) {
            std::optional<Connection> connected = connect_to_server(
                global.server, global.token, global.tls_ca, global.tls_server_name);
            if (!connected) return 2;
            c = std::move(*connected);
        }
        return command->run(c, args);
    } catch (const render::UsageError& e) {
        usage_error(e.what());
    } catch (const RpcFailure& e) {
        std::fprintf(stderr, "client: %s (server %s)%s\n", e.what(), global.server.c_str(),
                     connection_hint(e.status, tls_used(global.tls_ca)).c_str());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "client: error: %s\n", e.what());
        return 1;
    }
}
