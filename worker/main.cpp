// `worker`: leases ranges of iterations from a render server, renders them, reports the sums.
//
//   worker --server HOST:PORT [--threads T] [--token T] [--cache DIR]

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "core/util/log.h"
#include "worker/rpc_common.h"
#include "worker/worker.h"

namespace {

using namespace render::service;

constexpr const char* kUsage = R"(usage:
  worker --server HOST:PORT [--threads T] [--token T] [--cache DIR]

options:
  --server HOST:PORT   the render server (default: env RENDER_SERVER, else 127.0.0.1:50051)
  --threads T          render threads (default 0: all cores; never changes the image)
  --token T            bearer token (default: env RENDER_TOKEN)
  --cache DIR          asset cache (default: $XDG_CACHE_HOME/render-worker, else
                       ~/.cache/render-worker, else /tmp/render-worker-$UID)

Logs are key=value lines on stderr. SIGTERM/SIGINT: finish the current range, report it and
exit 0; a second signal gives the range up at once.
)";

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "worker: " << message << "\n\n" << kUsage;
    std::exit(2);
}

extern "C" void on_signal(int) {
    g_stop_requests.fetch_add(1);
}

std::filesystem::path default_cache() {
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
        return std::filesystem::path(xdg) / "render-worker";
    if (const char* home = std::getenv("HOME"); home && *home)
        return std::filesystem::path(home) / ".cache" / "render-worker";
    return "/tmp/render-worker-" + std::to_string(getuid());
}

}  // namespace

int main(int argc, char** argv) {
    WorkerOptions options;
    if (const char* env = std::getenv("RENDER_SERVER"); env && *env) options.server = env;
    std::string token;
    std::vector<std::string> args(argv + 1, argv + argc);
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= args.size()) usage_error(a + " needs a value");
            return args[++i];
        };
        if (a == "--server") {
            options.server = value();
        } else if (a == "--threads") {
            std::string v = value();
            std::istringstream in(v);
            if (!(in >> options.threads) || !in.eof() || options.threads < 0)
                usage_error("--threads expects a number >= 0, got \"" + v + "\"");
        } else if (a == "--token") {
            token = value();
        } else if (a == "--cache") {
            options.cache_dir = value();
        } else if (a == "--help" || a == "-h") {
            std::cout << kUsage;
            return 0;
        } else {
            usage_error("unknown argument " + a);
        }
    }
    if (options.server.empty()) options.server = "127.0.0.1:50051";
    options.token = token_or_env(token);
    if (options.cache_dir.empty()) options.cache_dir = default_cache();

    struct sigaction action {};
    action.sa_handler = on_signal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGTERM, &action, nullptr);
    sigaction(SIGINT, &action, nullptr);
    std::signal(SIGPIPE, SIG_IGN);

    try {
        Worker worker(options);
        return worker.run();
    } catch (const std::exception& e) {
        render::log_error("fatal").kv("error", e.what());
        return 1;
    }
}
