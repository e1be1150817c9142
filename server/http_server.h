#pragma once

// The server's HTTP side (cpp-httplib): /metrics (Prometheus text format), and with the
// dashboard the page itself (assets embedded at build time, server/dashboard/), and JSON under
// /api/ mirroring the gRPC reads plus cancel and priority. /api/ takes the same bearer token
// as the gRPC API (header `Authorization: Bearer T`); /metrics and the page's static files
// need none. Endpoints: docs/guide/service.md, "HTTP".

#include <memory>
#include <string>
#include <thread>

#include "server/auth.h"
#include "server/job_manager.h"

namespace httplib {
class Server;
}

namespace render::server {

class HttpServer {
  public:
    // `dashboard`: serve the page and /api/ besides /metrics.
    HttpServer(JobManager& manager, const Auth& auth, bool dashboard);
    ~HttpServer();
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    // Binds HOST:PORT (port 0: any free port) and serves from a thread of its own; returns the
    // port, or 0 when it cannot bind.
    int start(const std::string& host, int port);
    void stop();

  private:
    JobManager& manager_;
    const Auth& auth_;
    std::unique_ptr<httplib::Server> http_;
    std::thread thread_;
};

// An embedded dashboard file by its URL path ("/", "/app.js"...): null for anything else, so
// that no request path ever reaches the file system.
struct EmbeddedAsset {
    const char* path;
    const char* content_type;
    const char* data;
    unsigned long size;
};
const EmbeddedAsset* find_dashboard_asset(const std::string& path);

}  // namespace render::server
