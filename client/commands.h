#pragma once

// The client's command table: one row per subcommand ({name, usage, help, run}). The usage
// text, main's dispatch and the "unknown command" error all come from it, and the global
// options (before the command) are declared once in global_parser(). Each command's work is
// in its own file: submit.cpp, watch.cpp, fetch.cpp, jobs.cpp (list, status, cancel, delete)
// and local_commands.cpp (bundle, hash: no server).

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "client/connection.h"
#include "core/util/arguments.h"

namespace render::service {

using Arguments = std::vector<std::string>;

struct Command {
    std::string name;
    std::string usage;  // as written after "client", e.g. "watch JOB"
    std::string help;
    // Whether it talks to the server: main connects (checking TLS and the token) before run,
    // which then gets the connection; otherwise run gets an unconnected one.
    bool remote = true;
    std::function<int(const Connection&, const Arguments&)> run;
};

const std::vector<Command>& commands();
const Command* find_command(const std::string& name);

// The options before the command.
struct GlobalOptions {
    std::string server;  // main falls back to env RENDER_SERVER, then 127.0.0.1:50051
    std::string token, tls_ca, tls_server_name;
};
render::ArgumentParser global_parser(GlobalOptions& o);

std::string usage();
// Prints "client: MESSAGE" and the usage, exits with status 2.
[[noreturn]] void usage_error(const std::string& message);
// The job id a command takes as its first argument; a usage error without one.
std::string job_argument(const Arguments& args, const std::string& command);

// submit.cpp
int submit(const Connection& c, const Arguments& args);
std::string submit_options_help();
// watch.cpp: progress until the job ends; 0 when it is DONE, else 1.
int watch(const Connection& c, const std::string& job_id);
// fetch.cpp
int fetch_command(const Connection& c, const Arguments& args);
int fetch_output(const Connection& c, const std::string& job_id, uint32_t frame_count,
                 std::optional<uint32_t> frame, bool preview, const std::string& out);
void check_output(const std::string& out, uint32_t frame_count);
// jobs.cpp
int list(const Connection& c);
int status(const Connection& c);
int cancel(const Connection& c, const std::string& job_id);
int delete_job(const Connection& c, const std::string& job_id);
// local_commands.cpp
int bundle_command(const Arguments& args);
int hash_command(const Arguments& args);

}  // namespace render::service
