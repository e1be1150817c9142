// `worker`: leases ranges of iterations from a render server, renders them, reports the sums.
//
//   worker --server HOST:PORT[,HOST:PORT...] [--threads T] [--token T] [--cache DIR]
//   [--cache-max-size SIZE]
//          [--max-memory SIZE] [--test-render-fault FAULT [--test-render-fault-scene NAME]]
//          [--tls-ca FILE [--tls-server-name NAME]]

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "core/base/memory_budget.h"
#include "core/util/arguments.h"
#include "core/util/log.h"
#include "service/process_setup.h"
#include "service/rpc.h"
#include "service/server_list.h"
#include "worker/worker.h"

namespace {

using namespace render;
using namespace render::service;

struct TlsFlags {
    std::string ca, server_name;
};

ArgumentParser make_parser(WorkerOptions& o, std::string& server, std::string& token, TlsFlags& tls,
                           bool& help) {
    ArgumentParser p;
    p.value({"--server"}, "HOST:PORT[,HOST:PORT...]",
            "the render server, or several servers of one farm in order of preference: the "
            "worker moves to the next when one cannot be reached (default: env RENDER_SERVER, "
            "else 127.0.0.1:50051)",
            [&](const std::string& v) { server = v; });
    p.value({"--threads"}, "T", "render threads (default 0: all cores; never changes the image)",
            [&](const std::string& v) {
                o.threads = parse_number<int>("--threads", v);
                if (o.threads < 0) throw UsageError("--threads must be >= 0");
            });
    p.value({"--max-memory"}, "SIZE",
            "memory a job's scene, film and the algorithm's working memory per iteration may "
            "take, e.g. 4G (default: the memory available when the scene is loaded); a job "
            "estimated to need more fails with that message",
            [&](const std::string& v) { o.max_memory = parse_size_flag("--max-memory", v); });
    p.value({"--token"}, "T", "bearer token (default: env RENDER_TOKEN)",
            [&](const std::string& v) { token = v; });
    p.value({"--cache"}, "DIR",
            "asset cache (default: $XDG_CACHE_HOME/render-worker, else ~/.cache/render-worker, "
            "else /tmp/render-worker-$UID)",
            [&](const std::string& v) { o.cache_dir = v; });
    p.value({"--cache-max-size"}, "SIZE",
            "bound on the asset cache, e.g. 20G (default 8G; 0: none): before fetching a job's "
            "assets the worker removes the least recently used job folders and assets until "
            "they fit; never the job in use",
            [&](const std::string& v) {
                o.cache_max_bytes = v == "0" ? 0 : parse_size_flag("--cache-max-size", v);
            });
    p.value({"--tls-ca"}, "FILE",
            "connect with TLS, trusting the CA certificate(s) in FILE (PEM; default: env "
            "RENDER_TLS_CA). Without it the connection is plaintext, and a token is only sent "
            "to a loopback address",
            [&](const std::string& v) { tls.ca = v; });
    p.value({"--tls-server-name"}, "NAME",
            "the name the server's certificate must carry, when it is not the host of --server "
            "(default: env RENDER_TLS_SERVER_NAME)",
            [&](const std::string& v) { tls.server_name = v; });
    p.value({"--test-render-fault"}, "FAULT",
            "tests only: the renderer fails every lease, with throw:MESSAGE (an exception "
            "carrying MESSAGE), non-std (an exception that is not a std::exception) or abort "
            "(the process aborts), as a renderer meeting what it cannot render would "
            "(docs/guide/reliability.md)",
            [&](const std::string& v) {
                const std::string scene = o.test_render_fault.scene_name;
                o.test_render_fault = RenderFault::parse(v);
                o.test_render_fault.scene_name = scene;
            });
    p.value({"--test-render-fault-scene"}, "NAME",
            "tests only: --test-render-fault fails only the leases of jobs whose scene file is "
            "named NAME (e.g. poison.xml)",
            [&](const std::string& v) { o.test_render_fault.scene_name = v; });
    p.flag({"--help", "-h"}, "this text", [&] { help = true; });
    return p;
}

std::string usage() {
    WorkerOptions unused_options;
    std::string unused_server, unused_token;
    TlsFlags unused_tls;
    bool unused_help = false;
    return "usage:\n  worker --server HOST:PORT[,HOST:PORT...] [options]\n\noptions:\n" +
           make_parser(unused_options, unused_server, unused_token, unused_tls, unused_help)
               .help() +
           "\nLogs are key=value lines on stderr. SIGTERM/SIGINT: finish the current range, "
           "report it and\nexit 0; a second signal gives the range up at once.\n";
}

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "worker: " << message << "\n\n" << usage();
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
    render::service::prepare_grpc_process();
    WorkerOptions options;
    std::string server;
    if (const char* env = std::getenv("RENDER_SERVER"); env && *env) server = env;
    std::string token;
    TlsFlags tls;
    bool help = false;
    try {
        make_parser(options, server, token, tls, help).parse(argc, argv);
    } catch (const UsageError& e) {
        usage_error(e.what());
    }
    if (help) {
        std::cout << usage();
        return 0;
    }
    if (options.test_render_fault.kind != RenderFault::Kind::kNone)
        render::log_warn("test_render_fault").kv("note", "every lease fails: a test worker");
    if (server.empty()) server = "127.0.0.1:50051";
    try {
        options.servers = split_server_list(server);
    } catch (const std::invalid_argument& e) {
        usage_error(std::string("--server: ") + e.what());
    }
    options.token = token_or_env(token);
    try {
        options.tls = client_tls_from(tls.ca, tls.server_name);
    } catch (const std::exception& e) {
        std::cerr << "worker: " << e.what() << "\n";
        return 2;
    }
    for (const std::string& address : options.servers)
        if (const std::string problem =
                check_client_transport(address, options.tls.tls, !options.token.empty());
            !problem.empty()) {
            std::cerr << "worker: " << problem << "\n";
            return 2;
        }
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
