// `server`: the render service's gRPC frontend.
//
//   server --listen HOST:PORT --store DIR|sqlite:FILE|postgresql://... [--data DIR]
//          [--token T] [--lease-timeout SECONDS]
//          [--heartbeat SECONDS] [--lease-seconds SECONDS] [--max-lease-seconds SECONDS]
//          [--checkpoint-seconds SECONDS]
//          [--max-job-assets SIZE] [--max-store-size SIZE] [--spool-reports-above SIZE]
//          [--stream-idle-timeout SECONDS]
//          [--max-transfer-streams N]
//          [--metrics HOST:PORT] [--http HOST:PORT] [--tls-cert FILE --tls-key FILE | --insecure]
//          [--health-listen HOST:PORT] [--advertise HOST:PORT] [--hold-seconds SECONDS]
//          [--peer-tls-ca FILE] [--store-connections N]
//
// The token may also come from the environment variable RENDER_TOKEN, the TLS files from
// RENDER_TLS_CERT and RENDER_TLS_KEY. A token without TLS needs --insecure on a loopback
// address (service/transport_security.h). With PORT 0 the kernel picks a port; once listening
// the server prints `listening on HOST:PORT` on stdout, then `metrics on HOST:PORT`,
// `http on HOST:PORT` and `health on HOST:PORT` for the extra listeners asked for (/metrics;
// the dashboard, /api/ and /metrics; the plaintext health service). Structured log lines go
// to stderr. SIGTERM/SIGINT: stop accepting, checkpoint, exit 0.

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/base/memory_budget.h"
#include "core/util/arguments.h"
#include "core/util/log.h"
#include "server/auth.h"
#include "server/http_server.h"
#include "server/job_manager.h"
#include "server/job_service.h"
#include "server/store/open_job_store.h"
#include "server/worker_service.h"
#include "service/process_setup.h"
#include "service/transport_security.h"

namespace {

using namespace render;
using namespace render::server;

struct Options {
    std::string listen;
    std::string token;
    std::string metrics;               // HOST:PORT for /metrics alone
    std::string http;                  // HOST:PORT for the dashboard, /api/ and /metrics
    std::string tls_cert, tls_key;     // PEM files; both empty: plaintext
    std::string peer_tls_ca;           // trusted for forwarding reports (default: tls_cert)
    bool insecure = false;             // a token over plaintext (loopback only)
    std::string health;                // HOST:PORT for grpc.health.v1 (no render API), plaintext
    bool fixed_stream_window = false;  // gRPC's bandwidth-delay probe off
    std::string store;                 // --store: a folder or a store URL
    std::string data;                  // --data: the files' folder beside a store URL
    ServerOptions server;
    bool help = false;
};

double parse_seconds(const std::string& flag, const std::string& text) {
    const double v = parse_number<double>(flag, text);
    if (!(v > 0) || v > 1e6) throw UsageError(flag + " expects seconds in (0, 1e6], got " + text);
    return v;
}

// A duration for the retention options: a number of seconds, or one with a unit s, m, h or
// d ("90", "30m", "7d"); "0" or "off" turns the rule off (returns 0).
double parse_duration(const std::string& flag, const std::string& text) {
    if (text == "0" || text == "off") return 0;
    double unit = 1;
    std::string number = text;
    if (!text.empty()) {
        switch (text.back()) {
            case 's':
                unit = 1;
                break;
            case 'm':
                unit = 60;
                break;
            case 'h':
                unit = 3600;
                break;
            case 'd':
                unit = 86400;
                break;
            default:
                unit = 0;
        }
        if (unit > 0)
            number.pop_back();
        else
            unit = 1;
    }
    double v = 0;
    try {
        v = parse_number<double>(flag, number) * unit;
    } catch (const UsageError&) {
        throw UsageError(flag + " expects a duration (90, 30m, 12h, 7d) or off, got " + text);
    }
    if (!(v > 0) || v > 10 * 365 * 86400.0)
        throw UsageError(flag + " expects a duration in (0, 3650d] or off, got " + text);
    return v;
}

ArgumentParser make_parser(Options& o) {
    ArgumentParser p;
    p.value({"--listen"}, "HOST:PORT", "address to serve on (required; port 0: any free port)",
            [&](const std::string& v) { o.listen = v; });
    p.value({"--store"}, "DIR|URL",
            "job store (required): a folder (SQLite database, assets, checkpoints, results), "
            "sqlite:FILE or postgresql://... (the database alone; files in --data)",
            [&](const std::string& v) { o.store = v; });
    p.value({"--data"}, "DIR",
            "assets, checkpoints and results when --store is a URL (required with postgresql://; "
            "default for sqlite:FILE: FILE's folder)",
            [&](const std::string& v) { o.data = v; });
    p.value({"--token"}, "T",
            "bearer token clients and workers must send (default: env "
            "RENDER_TOKEN)",
            [&](const std::string& v) { o.token = v; });
    p.value({"--lease-timeout"}, "SECONDS",
            "a lease not heartbeaten for this long expires (default 30)",
            [&](const std::string& v) {
                o.server.lease_timeout_seconds = parse_seconds("--lease-timeout", v);
            });
    p.value({"--heartbeat"}, "SECONDS", "how often workers heartbeat (default 2)",
            [&](const std::string& v) {
                o.server.heartbeat_seconds = parse_seconds("--heartbeat", v);
            });
    p.value({"--lease-seconds"}, "SECONDS",
            "how long a lease should take at the worker's measured rate (default 3): shorter "
            "leases merge (and refresh previews) more often, at more report traffic",
            [&](const std::string& v) {
                o.server.target_lease_seconds = parse_seconds("--lease-seconds", v);
            });
    p.value({"--max-lease-seconds"}, "SECONDS",
            "a lease of several iterations lasts at most this long at the worker's measured "
            "rate (default 30; one iteration longer than this is a lease of its own): longer "
            "leases send fewer reports of a large frame, and lose more when a worker dies",
            [&](const std::string& v) {
                o.server.max_lease_seconds = parse_seconds("--max-lease-seconds", v);
            });
    p.value({"--checkpoint-seconds"}, "SECONDS",
            "write a frame's merged sums to its checkpoint at most this often (default 30; 0: "
            "after every report); a crash re-renders what merged since the last checkpoint",
            [&](const std::string& v) {
                o.server.checkpoint_seconds =
                    v == "0" ? 0.0 : parse_seconds("--checkpoint-seconds", v);
            });
    p.value({"--report-delay"}, "SECONDS",
            "for tests and measurements: hold each report this long after its values arrive, "
            "before merging it, as a slow network or a busy server would (default 0)",
            [&](const std::string& v) {
                o.server.report_delay_seconds = parse_seconds("--report-delay", v);
            });
    p.value({"--submit-validation-seconds"}, "SECONDS",
            "refuse an animation whose frames' scenes would take longer than this to load at "
            "submit (every frame is loaded to validate it; default 120)",
            [&](const std::string& v) {
                o.server.submit_validation_seconds =
                    parse_seconds("--submit-validation-seconds", v);
            });
    p.value({"--max-job-assets"}, "SIZE",
            "the largest a job's assets may be in all, and so any one asset (K, M, G or T "
            "suffix; default and at most 16G); a larger bundle or upload is refused with "
            "RESOURCE_EXHAUSTED",
            [&](const std::string& v) {
                o.server.max_job_assets = parse_size_flag("--max-job-assets", v);
                if (o.server.max_job_assets > kMaxBundleSize)
                    throw UsageError("--max-job-assets is at most 16G");
            });
    p.value({"--max-store-size"}, "SIZE",
            "the largest the asset store may grow, every uploaded asset in all (K, M, G or T "
            "suffix; default 100G); an upload that does not fit is refused with "
            "RESOURCE_EXHAUSTED before a byte is written",
            [&](const std::string& v) {
                o.server.max_store_size = parse_size_flag("--max-store-size", v);
            });
    p.value({"--spool-reports-above"}, "SIZE",
            "a report of at least SIZE bytes of values is written to a file in the store while "
            "it arrives and merged from there, instead of held in memory beside the frame's "
            "sums (K, M, G or T suffix; default 64M: a 1920x1080 report of several iterations "
            "is spooled; 0: every report; off: none)",
            [&](const std::string& v) {
                o.server.spool_reports_above = v == "off" ? UINT64_MAX
                                               : v == "0"
                                                   ? 0
                                                   : parse_size_flag("--spool-reports-above", v);
            });
    p.value({"--stream-idle-timeout"}, "SECONDS",
            "cancel an UploadAsset, FetchResult, FetchAsset, Report or WatchJob stream that "
            "sends or takes no chunk for this long, freeing its server thread; a cancelled "
            "Report's lease is queued again at once (default 60)",
            [&](const std::string& v) {
                o.server.streams.idle_seconds = parse_seconds("--stream-idle-timeout", v);
            });
    p.value({"--memory-wait"}, "SECONDS",
            "a job that every live worker refused for memory (its estimate over the worker's "
            "limit) waits this long for a worker with more memory, then FAILS with the "
            "refusal's message (default 300); refusals never count toward the poison rule",
            [&](const std::string& v) {
                o.server.memory_wait_seconds = parse_seconds("--memory-wait", v);
            });
    p.value({"--retain-finished"}, "DURATION",
            "delete a finished, failed or cancelled job (rows, folders, results, assets no "
            "other job uses, as `client delete`) this long after it finished: seconds or "
            "30m, 12h, 7d (default off: jobs stay until deleted)",
            [&](const std::string& v) {
                o.server.retain_finished_seconds = parse_duration("--retain-finished", v);
            });
    p.value({"--unreferenced-asset-grace"}, "DURATION",
            "remove an uploaded asset that no job references once it was last uploaded or "
            "named in HasAssets this long ago (a client that uploaded and never submitted): "
            "seconds or 30m, 12h, 7d, or off (default 24h)",
            [&](const std::string& v) {
                o.server.unreferenced_asset_seconds =
                    parse_duration("--unreferenced-asset-grace", v);
            });
    p.value({"--max-transfer-streams"}, "N",
            "at most N clients' UploadAsset and FetchResult streams open at once, and N "
            "workers' FetchAsset streams; past it RESOURCE_EXHAUSTED (default 64)",
            [&](const std::string& v) {
                const int n = parse_number<int>("--max-transfer-streams", v);
                if (n < 1) throw UsageError("--max-transfer-streams must be >= 1");
                o.server.streams.max_streams = size_t(n);
            });
    p.value({"--metrics"}, "HOST:PORT",
            "serve Prometheus metrics at http://HOST:PORT/metrics (port 0: any free port)",
            [&](const std::string& v) { o.metrics = v; });
    p.value({"--http"}, "HOST:PORT",
            "serve the web dashboard, its JSON API under /api/ and /metrics (port 0: any)",
            [&](const std::string& v) { o.http = v; });
    p.value({"--tls-cert"}, "FILE",
            "serve TLS with this certificate (PEM, the server's first, then any intermediates; "
            "default: env RENDER_TLS_CERT); needs --tls-key",
            [&](const std::string& v) { o.tls_cert = v; });
    p.value({"--tls-key"}, "FILE",
            "the private key of --tls-cert (PEM; default: env RENDER_TLS_KEY)",
            [&](const std::string& v) { o.tls_key = v; });
    p.flag({"--insecure"},
           "accept the token over plaintext; only on a loopback --listen address (a token "
           "without TLS is refused otherwise)",
           [&] { o.insecure = true; });
    p.value({"--health-listen"}, "HOST:PORT",
            "also serve the gRPC health service (grpc.health.v1), without the render API, in "
            "plaintext at HOST:PORT: for probes that cannot speak TLS, e.g. Kubernetes' gRPC "
            "probes",
            [&](const std::string& v) { o.health = v; });
    p.flag({"--fixed-stream-window"},
           "keep every stream's receive window at gRPC's 64 KiB (its bandwidth-delay probe "
           "off): reports waiting for their job's turn then buffer 64 KiB each instead of "
           "megabytes (server memory with many workers reporting large frames); slower "
           "transfers over links with latency",
           [&] { o.fixed_stream_window = true; });
    p.value({"--advertise"}, "HOST:PORT",
            "with several servers on one PostgreSQL store: the address clients and workers "
            "reach this server at, recorded with the jobs it holds (default: --listen)",
            [&](const std::string& v) { o.server.advertise_address = v; });
    p.value({"--peer-tls-ca"}, "FILE",
            "with several servers on one PostgreSQL store and TLS: the certificate authority "
            "(PEM) the other servers' certificates are checked against when a report is "
            "forwarded to the server holding its job (default: --tls-cert itself)",
            [&](const std::string& v) { o.peer_tls_ca = v; });
    p.value(
        {"--hold-seconds"}, "SECONDS",
        "with several servers on one PostgreSQL store: how long this server's hold of a "
        "job's sums lasts without renewal (renewed every quarter of it); a server that "
        "dies is taken over this long after its last renewal (default 10)",
        [&](const std::string& v) { o.server.hold_seconds = parse_seconds("--hold-seconds", v); });
    p.value({"--store-connections"}, "N",
            "with a PostgreSQL store: the connections this server keeps to it, one per "
            "operation at a time (default " +
                std::to_string(kDefaultStoreConnections) + ")",
            [&](const std::string& v) {
                const int n = parse_number<int>("--store-connections", v);
                if (n < 1 || n > 256) throw UsageError("--store-connections takes 1 to 256");
                o.server.store_connections = size_t(n);
            });
    p.flag({"--help", "-h"}, "this text", [&] { o.help = true; });
    return p;
}

std::string usage() {
    Options unused;
    return "usage: server --listen HOST:PORT --store DIR|URL [--data DIR] [options]\n\noptions:\n" +
           make_parser(unused).help();
}

std::optional<std::pair<std::string, int>> split_address(const std::string& address);

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "server: " << message << "\n\n" << usage();
    std::exit(2);
}

Options parse(int argc, char** argv) {
    Options o;
    if (const char* env = std::getenv("RENDER_TOKEN")) o.token = env;
    try {
        make_parser(o).parse(argc, argv);
    } catch (const UsageError& e) {
        usage_error(e.what());
    }
    if (o.help) {
        std::cout << usage();
        std::exit(0);
    }
    if (o.listen.empty()) usage_error("--listen HOST:PORT is required");
    if (o.store.empty()) usage_error("--store DIR (or a store URL) is required");
    if (!is_store_url(o.store)) {
        if (!o.data.empty()) usage_error("--data goes with a store URL; --store DIR holds both");
        o.server.store = o.store;
    } else {
        o.server.database = o.store;
        const std::string sqlite_file = sqlite_url_path(o.store);
        if (o.store.rfind("sqlite:", 0) == 0 && sqlite_file.empty())
            usage_error("--store sqlite:FILE names no file");
        if (!o.data.empty())
            o.server.store = o.data;
        else if (!sqlite_file.empty())
            o.server.store = std::filesystem::absolute(sqlite_file).parent_path();
        else
            usage_error("--store " + redact_store_url(o.store) +
                        " needs --data DIR (assets, checkpoints, results)");
    }
    if (o.listen.rfind(':') == std::string::npos) usage_error("--listen expects HOST:PORT");
    if (o.server.advertise_address.empty()) o.server.advertise_address = o.listen;
    for (const auto& [flag, value] : {std::pair{"--metrics", &o.metrics}, {"--http", &o.http}})
        if (!value->empty() && !split_address(*value))
            usage_error(std::string(flag) + " expects HOST:PORT, got " + *value);
    if (!o.health.empty() && o.health.rfind(':') == std::string::npos)
        usage_error("--health-listen expects HOST:PORT, got " + o.health);
    o.tls_cert = service::flag_or_env(o.tls_cert, "RENDER_TLS_CERT");
    o.tls_key = service::flag_or_env(o.tls_key, "RENDER_TLS_KEY");
    if (o.tls_cert.empty() != o.tls_key.empty())
        usage_error(o.tls_cert.empty() ? "--tls-key needs --tls-cert FILE (env RENDER_TLS_CERT)"
                                       : "--tls-cert needs --tls-key FILE (env RENDER_TLS_KEY)");
    const bool tls = !o.tls_cert.empty();
    for (const std::string& problem :
         {service::check_server_transport(o.listen, tls, !o.token.empty(), o.insecure),
          service::check_http_transport(o.http, !o.token.empty())})
        if (!problem.empty()) {
            std::cerr << "server: " << problem << "\n";
            std::exit(2);
        }
    return o;
}

// HOST:PORT ([::1]:PORT for IPv6) to a host httplib binds and a port in [0, 65535].
std::optional<std::pair<std::string, int>> split_address(const std::string& address) {
    const size_t colon = address.rfind(':');
    if (colon == std::string::npos || colon == 0) return std::nullopt;
    std::string host = address.substr(0, colon);
    const std::string port = address.substr(colon + 1);
    if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != port.npos)
        return std::nullopt;
    const int p = std::stoi(port);
    if (p > 65535) return std::nullopt;
    if (host.size() > 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    return std::pair{host, p};
}

std::string shown_host(std::string host) {
    if (host.empty() || host == "0.0.0.0" || host == "[::]" || host == "::" || host == "localhost")
        return "127.0.0.1";
    return host;
}

}  // namespace

int main(int argc, char** argv) {
    render::service::prepare_grpc_process();
    Options options = parse(argc, argv);

    // Signals are taken by sigwait below; block them before gRPC starts its threads.
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGTERM);
    sigaddset(&signals, SIGINT);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    signal(SIGPIPE, SIG_IGN);

    std::unique_ptr<JobManager> manager;
    try {
        manager = std::make_unique<JobManager>(options.server);
    } catch (const std::exception& e) {
        Log("error", "store_open_failed")
            .kv("store", redact_store_url(options.store))
            .kv("error", e.what());
        std::cerr << "server: cannot open the store " << redact_store_url(options.store) << ": "
                  << e.what() << "\n";
        return 1;
    }
    Auth auth(options.token);
    std::atomic<bool> stopping{false};
    JobServiceImpl job_service(*manager, auth, stopping);
    // Reports for leases another server of a shared store granted go to that server
    // (docs/design/job-store.md, "Reports reaching a non-holder"); over TLS they are checked
    // against --peer-tls-ca, else against this server's own certificate.
    std::string peer_root_pem;
    if (!options.tls_cert.empty()) {
        const bool ca = !options.peer_tls_ca.empty();
        try {
            peer_root_pem =
                service::read_pem_file(ca ? "--peer-tls-ca" : "--tls-cert",
                                       ca ? options.peer_tls_ca : options.tls_cert, "CERTIFICATE");
        } catch (const std::exception& e) {
            std::cerr << "server: " << e.what() << "\n";
            Log("error", "tls_files_unreadable").kv("error", e.what());
            return 2;  // a configuration error: restarting does not help
        }
    }
    ReportForwarder report_forwarder(options.token, peer_root_pem);
    WorkerServiceImpl worker_service(*manager, auth, &report_forwarder);

    std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
    const bool tls = !options.tls_cert.empty();
    if (tls) {
        grpc::SslServerCredentialsOptions ssl;
        try {
            ssl.pem_key_cert_pairs.push_back(
                {service::read_pem_file("--tls-key", options.tls_key, "PRIVATE KEY"),
                 service::read_pem_file("--tls-cert", options.tls_cert, "CERTIFICATE")});
        } catch (const std::exception& e) {
            std::cerr << "server: " << e.what() << "\n";
            Log("error", "tls_files_unreadable").kv("error", e.what());
            return 2;  // a configuration error: restarting does not help
        }
        credentials = grpc::SslServerCredentials(ssl);
    }

    grpc::EnableDefaultHealthCheckService(true);
    grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort(options.listen, credentials, &port);
    builder.RegisterService(&job_service);
    builder.RegisterService(&worker_service);
    // gRPC's synchronous server keeps at most MAX_POLLERS idle threads (default 2) and makes
    // and ends threads as calls come and go; with hundreds of workers that churn cost ~10 % of
    // the server's CPU per lease (farm_sim, docs/results/service-measurements.md "How many workers
    // one server carries"). Eight idle threads cost nothing and keep them.
    builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::MAX_POLLERS, 8);
    // Reports of one job are received one at a time (JobManager::report_slot), but gRPC keeps
    // reading the waiting ones into memory as far as their window allows, and its
    // bandwidth-delay probe grows that window to megabytes on a fast link: with 16 workers
    // reporting 1024x1024 frames, tens of MB each (docs/results/service-measurements.md).
    if (options.fixed_stream_window) builder.AddChannelArgument(GRPC_ARG_HTTP2_BDP_PROBE, 0);
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    if (!server || port == 0) {
        std::cerr << "server: cannot listen on " << options.listen
                  << (tls ? " (with TLS: does --tls-key " + options.tls_key +
                                " belong to --tls-cert " + options.tls_cert + "?)"
                          : std::string())
                  << "\n";
        Log("error", "listen_failed").kv("address", options.listen);
        return 1;
    }
    // A --listen port of 0 (tests): the holds advertise the port bound, where other servers
    // forward reports (before the tick thread takes any hold).
    if (const std::string& a = options.server.advertise_address;
        a.size() > 2 && a.compare(a.size() - 2, 2, ":0") == 0)
        manager->set_advertise_address(a.substr(0, a.size() - 1) + std::to_string(port));
    // The health service without the render API, in plaintext, for probes that cannot speak
    // TLS (server reflection comes along: the reflection library adds it to every server).
    std::unique_ptr<grpc::Server> health_server;
    std::string health_line;
    if (!options.health.empty()) {
        grpc::ServerBuilder health_builder;
        int health_port = 0;
        health_builder.AddListeningPort(options.health, grpc::InsecureServerCredentials(),
                                        &health_port);
        health_server = health_builder.BuildAndStart();
        if (!health_server || health_port == 0) {
            std::cerr << "server: cannot listen on " << options.health << " (--health-listen)\n";
            Log("error", "listen_failed").kv("address", options.health);
            server->Shutdown();
            return 1;
        }
        health_line = "health on " +
                      shown_host(options.health.substr(0, options.health.rfind(':'))) + ":" +
                      std::to_string(health_port) + "\n";
    }
    const std::string host = shown_host(options.listen.substr(0, options.listen.rfind(':')));
    // The HTTP listeners are bound before anything is printed, so that the lines come together.
    std::vector<std::pair<std::string, std::unique_ptr<HttpServer>>> http_servers;
    std::string http_lines;
    for (const auto& [name, address] :
         {std::pair{"metrics", options.metrics}, std::pair{"http", options.http}}) {
        if (address.empty()) continue;
        const auto [http_host, http_port] = *split_address(address);
        auto http = std::make_unique<HttpServer>(*manager, auth, std::string(name) == "http");
        const int bound = http->start(http_host, http_port);
        if (bound == 0) {
            std::cerr << "server: cannot listen on " << address << " (--" << name << ")\n";
            Log("error", "listen_failed").kv("address", address);
            server->Shutdown();
            if (health_server) health_server->Shutdown();
            return 1;
        }
        http_lines +=
            std::string(name) + " on " + shown_host(http_host) + ":" + std::to_string(bound) + "\n";
        Log("info", "http_listening")
            .kv("what", name)
            .kv("address", shown_host(http_host) + ":" + std::to_string(bound));
        http_servers.emplace_back(name, std::move(http));
    }
    std::printf("listening on %s:%d\n%s%s", host.c_str(), port, http_lines.c_str(),
                health_line.c_str());
    std::fflush(stdout);
    Log("info", "listening")
        .kv("address", host + ":" + std::to_string(port))
        .kv("store", redact_store_url(options.store))
        .kv("data", options.server.store.string())
        .kv("auth", auth.enabled() ? "token" : "none")
        .kv("transport", tls ? "tls" : "plaintext")
        .kv("lease_timeout", options.server.lease_timeout_seconds)
        .kv("heartbeat", options.server.heartbeat_seconds);

    if (!tls && !service::is_loopback_address(options.listen))
        Log("warn", "plaintext_listener")
            .kv("address", options.listen)
            .kv("hint",
                "calls and images travel unencrypted and anyone who reaches the address may "
                "use the API; give --tls-cert/--tls-key and a token");

    std::atomic<bool> ticker_stop{false};
    std::thread ticker([&] {
        while (!ticker_stop) {
            try {
                manager->tick();
            } catch (const std::exception& e) {
                Log("error", "tick_failed").kv("error", e.what());
            }
            std::this_thread::sleep_for(std::chrono::duration<double>(kTickSeconds));
        }
    });

    int sig = 0;
    sigwait(&signals, &sig);
    Log("info", "shutting_down").kv("signal", sig == SIGTERM ? "SIGTERM" : "SIGINT");
    stopping = true;
    for (auto& [name, http] : http_servers) http->stop();
    if (health_server) health_server->Shutdown();
    server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(5));
    ticker_stop = true;
    ticker.join();
    manager->checkpoint_all();
    manager.reset();
    Log("info", "stopped");
    return 0;
}
