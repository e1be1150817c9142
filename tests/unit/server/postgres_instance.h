#pragma once

// A PostgreSQL server of the test's own: initdb in a temporary folder, started on a free port
// of 127.0.0.1 with trust authentication, stopped and removed by the destructor. PostgreSQL
// refuses to run as root, so under root it runs as the `postgres` user (runuser). When the
// binaries (env RENDER_PG_BIN, else /usr/lib/postgresql/*/bin, else PATH) or a user to run them
// as are missing, `skip_reason()` says why and the test skips (never passes): scripts/setup
// installs postgresql-15.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace render::testing {

class PostgresInstance {
  public:
    PostgresInstance() { start(); }
    ~PostgresInstance() { stop(); }
    PostgresInstance(const PostgresInstance&) = delete;
    PostgresInstance& operator=(const PostgresInstance&) = delete;

    // Non-empty when the server could not be started: why (then url() is empty).
    const std::string& skip_reason() const { return skip_reason_; }
    // A libpq URI of `database` on this server (the `postgres` database exists from initdb).
    std::string url(const std::string& database = "postgres") const {
        if (port_ == 0) return "";
        return "postgresql://render@127.0.0.1:" + std::to_string(port_) + "/" + database;
    }
    // Runs `sql` with psql on the `postgres` database; false when psql failed.
    bool psql(const std::string& sql) const {
        return run(bin("psql") + " -q -v ON_ERROR_STOP=1 -h 127.0.0.1 -p " + std::to_string(port_) +
                   " -U render -d postgres -c " + quote(sql)) == 0;
    }

    // Stops the server (immediately, as a crash would) and starts it again on the same port;
    // false when it did not come back.
    bool restart() {
        const std::string data = quote((dir_ / "data").string());
        run(as_user(bin("pg_ctl") + " -D " + data + " -m immediate -w stop"));
        const std::string options = "-p " + std::to_string(port_) + " -k " + dir_.string() +
                                    " -c listen_addresses=127.0.0.1 -c fsync=off";
        return run(as_user(bin("pg_ctl") + " -D " + data + " -l " + quote((dir_ / "log").string()) +
                           " -o " + quote(options) + " -w -t 60 start")) == 0;
    }

  private:
    static std::string quote(const std::string& s) {
        std::string out = "'";
        for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
        return out + "'";
    }
    static int run(const std::string& command) {
        const int rc = std::system((command + " >/dev/null 2>&1").c_str());
        return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    }
    std::string bin(const std::string& tool) const { return quote((bin_dir_ / tool).string()); }
    // `command` as the user PostgreSQL runs as.
    std::string as_user(const std::string& command) const {
        return runuser_.empty() ? command : runuser_ + " " + quote(command);
    }

    static std::filesystem::path find_bin_dir() {
        namespace fs = std::filesystem;
        if (const char* env = std::getenv("RENDER_PG_BIN"))
            if (fs::exists(fs::path(env) / "initdb")) return env;
        std::vector<fs::path> found;
        std::error_code ec;
        for (const auto& e : fs::directory_iterator("/usr/lib/postgresql", ec))
            if (fs::exists(e.path() / "bin" / "initdb")) found.push_back(e.path() / "bin");
        if (!found.empty()) {
            // The newest: version folders are numbers (15, 16, ...).
            std::sort(found.begin(), found.end(), [](const fs::path& a, const fs::path& b) {
                return std::atoi(a.parent_path().filename().c_str()) <
                       std::atoi(b.parent_path().filename().c_str());
            });
            return found.back();
        }
        if (const char* path = std::getenv("PATH")) {
            std::stringstream dirs(path);
            for (std::string d; std::getline(dirs, d, ':');)
                if (!d.empty() && fs::exists(fs::path(d) / "initdb") &&
                    fs::exists(fs::path(d) / "pg_ctl"))
                    return d;
        }
        return {};
    }

    static int free_port() {
        const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
        if (fd < 0) return 0;
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t len = sizeof addr;
        int port = 0;
        if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
            ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
            port = ntohs(addr.sin_port);
        ::close(fd);
        return port;
    }

    void start() {
        namespace fs = std::filesystem;
        bin_dir_ = find_bin_dir();
        if (bin_dir_.empty() || !fs::exists(bin_dir_ / "pg_ctl")) {
            skip_reason_ =
                "PostgreSQL's initdb and pg_ctl not found (RENDER_PG_BIN, "
                "/usr/lib/postgresql/*/bin, PATH); scripts/setup installs postgresql-15";
            return;
        }
        if (::geteuid() == 0) {
            const passwd* user = ::getpwnam("postgres");
            if (!user) {
                skip_reason_ =
                    "running as root (PostgreSQL refuses to) and no `postgres` user "
                    "to run it as";
                return;
            }
            runuser_ = "runuser -u postgres -- sh -c";
            uid_ = user->pw_uid;
            gid_ = user->pw_gid;
        }
        char pattern[] = "/tmp/render-pg-XXXXXX";
        if (!::mkdtemp(pattern)) {
            skip_reason_ = "cannot create a temporary folder for PostgreSQL";
            return;
        }
        dir_ = pattern;
        if (runuser_.size() && ::chown(dir_.c_str(), uid_, gid_) != 0) {
            skip_reason_ = "cannot give the temporary folder to the postgres user";
            return;
        }
        const std::string data = (dir_ / "data").string();
        if (run(as_user(bin("initdb") + " -D " + quote(data) +
                        " -A trust -U render -E UTF8 --no-sync")) != 0) {
            failure("initdb failed");
            return;
        }
        // A port found free may be taken before the server binds it: a few tries.
        for (int attempt = 0; attempt < 5 && port_ == 0; ++attempt) {
            const int port = free_port();
            const std::string options = "-p " + std::to_string(port) + " -k " + dir_.string() +
                                        " -c listen_addresses=127.0.0.1 -c fsync=off";
            if (run(as_user(bin("pg_ctl") + " -D " + quote(data) + " -l " +
                            quote((dir_ / "log").string()) + " -o " + quote(options) +
                            " -w -t 60 start")) == 0)
                port_ = port;
        }
        if (port_ == 0) failure("pg_ctl start failed");
    }

    // The environment is there but starting failed: a test failure to report, not a skip.
    void failure(const std::string& what) {
        std::ifstream log(dir_ / "log");
        std::stringstream text;
        text << log.rdbuf();
        skip_reason_.clear();
        start_error_ = what + "\n" + text.str();
    }

    void stop() {
        if (port_ != 0)
            run(as_user(bin("pg_ctl") + " -D " + quote((dir_ / "data").string()) +
                        " -m immediate -w stop"));
        if (!dir_.empty()) {
            std::error_code ec;
            std::filesystem::remove_all(dir_, ec);
        }
    }

  public:
    // Non-empty when the binaries were there but the server did not start (initdb's or
    // pg_ctl's failure, with the server log): the test fails with it.
    const std::string& start_error() const { return start_error_; }

  private:
    std::filesystem::path bin_dir_;
    std::filesystem::path dir_;
    std::string runuser_;
    uid_t uid_ = 0;
    gid_t gid_ = 0;
    int port_ = 0;
    std::string skip_reason_;
    std::string start_error_;
};

}  // namespace render::testing
