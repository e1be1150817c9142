#include "client/commands.h"

#include <cstdlib>
#include <iostream>

#include "core/render/algorithms.h"

namespace render::service {

const std::vector<Command>& commands() {
    auto one_job = [](const char* name, int (*run)(const Connection&, const std::string&)) {
        return [name, run](const Connection& c, const Arguments& args) {
            if (args.size() != 1) usage_error(std::string(name) + " expects one job id");
            return run(c, job_argument(args, name));
        };
    };
    static const std::vector<Command> table = {
        {"submit", "submit SCENE.xml [options]",
         "pack the scene and the files it references, upload what the server lacks, submit a "
         "job and print its id",
         true, submit},
        {"watch", "watch JOB", "progress until the job ends; exit status 1 unless it is DONE", true,
         one_job("watch", watch)},
        {"fetch", "fetch JOB [--frame F] [--preview] --out FILE.exr|DIR",
         "download a frame's EXR (--preview: the current average); --out DIR (a name not "
         "ending in .exr) without --frame writes every frame as DIR/frame_0000.exr, "
         "frame_0001.exr, ... (frame numbers are the job's frame indices, from 0); a job of "
         "several frames needs --out DIR or --frame F",
         true, fetch_command},
        {"cancel", "cancel JOB", "cancel a job", true, one_job("cancel", cancel)},
        {"delete", "delete JOB",
         "delete a finished, failed or cancelled job: its results and the assets no other job "
         "uses",
         true, one_job("delete", delete_job)},
        {"list", "list", "all jobs", true,
         [](const Connection& c, const Arguments&) { return list(c); }},
        {"status", "status", "workers and queue", true,
         [](const Connection& c, const Arguments&) { return status(c); }},
        {"bundle", "bundle SCENE.xml [-D k=v]",
         "list the files `submit` would upload, with their SHA-256", false,
         [](const Connection&, const Arguments& args) { return bundle_command(args); }},
        {"hash", "hash FILE...", "print the SHA-256 of files (as the asset store names them)",
         false, [](const Connection&, const Arguments& args) { return hash_command(args); }},
    };
    return table;
}

const Command* find_command(const std::string& name) {
    for (const Command& c : commands())
        if (c.name == name) return &c;
    return nullptr;
}

render::ArgumentParser global_parser(GlobalOptions& o) {
    render::ArgumentParser p;
    p.value({"--server"}, "HOST:PORT[,HOST:PORT...]",
            "the server, or several servers of one farm: the first that answers is used, and a "
            "watch moves to the next when it goes away (default: env RENDER_SERVER, else "
            "127.0.0.1:50051)",
            [&](const std::string& v) { o.server = v; });
    p.value({"--token"}, "T", "bearer token (default: env RENDER_TOKEN)",
            [&](const std::string& v) { o.token = v; });
    p.value({"--tls-ca"}, "FILE",
            "connect with TLS, trusting the CA certificate(s) in FILE (PEM; default: env "
            "RENDER_TLS_CA); without it the connection is plaintext and a token is only sent to "
            "a loopback address",
            [&](const std::string& v) { o.tls_ca = v; });
    p.value({"--tls-server-name"}, "NAME",
            "the name the server's certificate must carry, when it is not the host of --server "
            "(default: env RENDER_TLS_SERVER_NAME)",
            [&](const std::string& v) { o.tls_server_name = v; });
    p.flag({"--help", "-h"}, "this text", [] {
        std::cout << usage();
        std::exit(0);
    });
    return p;
}

std::string usage() {
    std::vector<std::pair<std::string, std::string>> rows;
    for (const Command& c : commands()) rows.emplace_back("  " + c.usage, c.help);
    GlobalOptions unused;
    return "usage:\n"
           "  client [global options] COMMAND ...\n\n"
           "commands:\n" +
           render::help_rows(rows) + "\nglobal options:\n" + global_parser(unused).help() +
           "\nsubmit options (the render options are those of `render`, with the same "
           "meaning):\n" +
           submit_options_help() + "\nalgorithms (--algo):\n" + render::algorithms_help() +
           "\nExit status: 0 on success, 1 on a failed call or job (the gRPC status is printed), "
           "2 on\nbad usage.\n";
}

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "client: " << message << "\n\n" << usage();
    std::exit(2);
}

std::string job_argument(const Arguments& args, const std::string& command) {
    if (args.empty() || args[0].empty() || args[0][0] == '-')
        usage_error(command + ": no job id given");
    return args[0];
}

}  // namespace render::service
