#include "server/http_server.h"

#include <google/protobuf/util/json_util.h>
#include <httplib.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>

#include "core/image/exr_io.h"
#include "core/util/log.h"
#include "server/dashboard_assets.h"

namespace render::server {

namespace fs = std::filesystem;

namespace {

int http_status(grpc::StatusCode code) {
    switch (code) {
        case grpc::StatusCode::OK:
            return 200;
        case grpc::StatusCode::INVALID_ARGUMENT:
            return 400;
        case grpc::StatusCode::UNAUTHENTICATED:
            return 401;
        case grpc::StatusCode::PERMISSION_DENIED:
            return 403;
        case grpc::StatusCode::NOT_FOUND:
            return 404;
        case grpc::StatusCode::FAILED_PRECONDITION:
            return 409;
        case grpc::StatusCode::UNAVAILABLE:
            return 503;
        default:
            return 500;
    }
}

std::string json_string(const std::string& s) {
    std::string out = "\"";
    for (unsigned char c : s) {
        if (c == '"' || c == '\\') {
            out += '\\';
            out += char(c);
        } else if (c < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            out += buf;
        } else {
            out += char(c);
        }
    }
    return out + "\"";
}

const char* code_name(grpc::StatusCode code) {
    switch (code) {
        case grpc::StatusCode::INVALID_ARGUMENT:
            return "INVALID_ARGUMENT";
        case grpc::StatusCode::UNAUTHENTICATED:
            return "UNAUTHENTICATED";
        case grpc::StatusCode::PERMISSION_DENIED:
            return "PERMISSION_DENIED";
        case grpc::StatusCode::NOT_FOUND:
            return "NOT_FOUND";
        case grpc::StatusCode::FAILED_PRECONDITION:
            return "FAILED_PRECONDITION";
        default:
            return "INTERNAL";
    }
}

void send_error(httplib::Response& res, const grpc::Status& status) {
    res.status = http_status(status.error_code());
    res.set_content("{\"error\":" + json_string(status.error_message()) + ",\"code\":\"" +
                        code_name(status.error_code()) + "\"}\n",
                    "application/json");
}

void send_message(httplib::Response& res, const google::protobuf::Message& message) {
    google::protobuf::util::JsonPrintOptions options;
    options.always_print_primitive_fields = true;
    options.preserve_proto_field_names = true;
    std::string json;
    if (!google::protobuf::util::MessageToJsonString(message, &json, options).ok()) {
        send_error(res, grpc::Status(grpc::StatusCode::INTERNAL, "cannot encode JSON"));
        return;
    }
    res.set_content(json, "application/json");
}

std::string random_suffix() {
    static thread_local std::mt19937_64 rng{std::random_device{}()};
    char buf[20];
    std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)rng());
    return buf;
}

// The frame index of a request (?frame=N, default 0); false when it is not a small number.
bool frame_param(const httplib::Request& req, uint32_t* frame) {
    *frame = 0;
    if (!req.has_param("frame")) return true;
    const std::string v = req.get_param_value("frame");
    if (v.empty() || v.size() > 6 || v.find_first_not_of("0123456789") != std::string::npos)
        return false;
    *frame = uint32_t(std::stoul(v));
    return true;
}

// Job ids as the server makes them (job-000001-abcdef); the route's pattern admits no more.
constexpr const char* kJob = R"(/api/jobs/([A-Za-z0-9_-]{1,80}))";

}  // namespace

const EmbeddedAsset* find_dashboard_asset(const std::string& path) {
    const std::string want = path == "/" ? "/index.html" : path;
    for (const EmbeddedAsset& a : kDashboardAssets)
        if (want == a.path) return &a;
    return nullptr;
}

HttpServer::HttpServer(JobManager& manager, const Auth& auth, bool dashboard)
    : manager_(manager), auth_(auth), http_(std::make_unique<httplib::Server>()) {
    httplib::Server& http = *http_;
    http.set_payload_max_length(64 * 1024);
    http.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
        res.set_content(manager_.metrics_text(), "text/plain; version=0.0.4; charset=utf-8");
    });
    if (!dashboard) return;

    // Static files: only the embedded table answers, never the file system.
    http.Get(R"(/[A-Za-z0-9._-]*)", [](const httplib::Request& req, httplib::Response& res) {
        const EmbeddedAsset* a = find_dashboard_asset(req.path);
        if (!a) {
            res.status = 404;
            res.set_content("not found\n", "text/plain");
            return;
        }
        res.set_header("Cache-Control", "no-cache");
        res.set_content(a->data, a->size, a->content_type);
    });

    // Every /api/ call checks the token first, as the gRPC services do. A POST from a page of
    // another origin is refused as well: without a token, a cancel would otherwise be a
    // cross-site request any web page could make from a browser on the same network.
    auto authorized = [this](const httplib::Request& req, httplib::Response& res) {
        if (req.method == "POST" && req.has_header("Origin") &&
            req.get_header_value("Origin") != "http://" + req.get_header_value("Host")) {
            send_error(res, grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                                         "cross-origin request refused"));
            return false;
        }
        const bool present = req.has_header("Authorization");
        const std::string value = present ? req.get_header_value("Authorization") : "";
        grpc::Status st = auth_.check_header(present, value);
        if (!st.ok()) send_error(res, st);
        return st.ok();
    };

    http.Get("/api/jobs", [this, authorized](const httplib::Request& req, httplib::Response& res) {
        if (!authorized(req, res)) return;
        v1::ListJobsReply reply;
        manager_.list(&reply);
        send_message(res, reply);
    });
    http.Get("/api/cluster",
             [this, authorized](const httplib::Request& req, httplib::Response& res) {
                 if (!authorized(req, res)) return;
                 v1::ClusterStatusReply reply;
                 manager_.cluster_status(&reply);
                 send_message(res, reply);
             });
    http.Get("/api/farm", [this, authorized](const httplib::Request& req, httplib::Response& res) {
        if (!authorized(req, res)) return;
        res.set_content(manager_.farm_json(), "application/json");
    });
    http.Get(kJob, [this, authorized](const httplib::Request& req, httplib::Response& res) {
        if (!authorized(req, res)) return;
        v1::Job job;
        if (grpc::Status st = manager_.get(req.matches[1], &job); !st.ok())
            return send_error(res, st);
        send_message(res, job);
    });
    http.Get(std::string(kJob) + "/history", [this, authorized](const httplib::Request& req,
                                                                httplib::Response& res) {
        if (!authorized(req, res)) return;
        uint32_t frame = 0;
        if (!frame_param(req, &frame))
            return send_error(
                res, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "frame must be a number"));
        std::vector<JobManager::ErrorPoint> points;
        if (grpc::Status st = manager_.error_history(req.matches[1], frame, &points); !st.ok())
            return send_error(res, st);
        std::ostringstream out;
        out.precision(9);
        out << "{\"frame\":" << frame << ",\"points\":[";
        for (size_t i = 0; i < points.size(); ++i) {
            const auto& p = points[i];
            out << (i ? "," : "") << "{\"seconds\":" << p.seconds
                << ",\"iterations\":" << p.iterations << ",\"relative_error\":"
                << (std::isfinite(p.relative_error) ? p.relative_error : 1.0) << "}";
        }
        out << "]}\n";
        res.set_content(out.str(), "application/json");
    });
    // A PNG of `image` through the image plugin, which writes files: a temporary one.
    auto send_png = [this](httplib::Response& res, const Image& image) {
        const fs::path file =
            manager_.assets().tmp_dir() / ("dashboard-" + random_suffix() + ".png");
        std::string bytes;
        try {
            write_png_preview(file, image);
            std::ifstream in(file, std::ios::binary);
            bytes.assign(std::istreambuf_iterator<char>(in), {});
        } catch (const std::exception& e) {
            std::error_code ec;
            fs::remove(file, ec);
            return send_error(res, grpc::Status(grpc::StatusCode::INTERNAL, e.what()));
        }
        std::error_code ec;
        fs::remove(file, ec);
        res.set_header("Cache-Control", "no-store");
        res.set_content(bytes, "image/png");
    };
    http.Get(std::string(kJob) + "/preview.png",
             [this, authorized, send_png](const httplib::Request& req, httplib::Response& res) {
                 if (!authorized(req, res)) return;
                 uint32_t frame = 0;
                 if (!frame_param(req, &frame))
                     return send_error(res, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                                         "frame must be a number"));
                 Image image;
                 if (grpc::Status st = manager_.preview_image(req.matches[1], frame, &image);
                     !st.ok())
                     return send_error(res, st);
                 send_png(res, image);
             });
    // The maps beside the preview (core/render/adaptive_maps.h): false colour, with the legend in
    // headers (X-Map-Low and X-Map-High: the values at the ramp's ends, X-Map-Scale: log or
    // linear, X-Map-Source: where the variance comes from).
    for (const bool variance : {true, false}) {
        http.Get(std::string(kJob) + (variance ? "/variance.png" : "/samples.png"),
                 [this, authorized, send_png, variance](const httplib::Request& req,
                                                        httplib::Response& res) {
                     if (!authorized(req, res)) return;
                     uint32_t frame = 0;
                     if (!frame_param(req, &frame))
                         return send_error(res, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                                             "frame must be a number"));
                     PixelMaps maps;
                     if (grpc::Status st = manager_.pixel_maps(req.matches[1], frame, &maps);
                         !st.ok())
                         return send_error(res, st);
                     if (variance && maps.variance.empty())
                         return send_error(
                             res, grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                                               "no per-pixel variance: the frame is done and its "
                                               "EXR has no variance layer (--layers variance)"));
                     const HeatMap map = heat_map(variance ? maps.variance : maps.samples,
                                                  maps.width, maps.height, variance);
                     char text[64];
                     std::snprintf(text, sizeof text, "%.6g", map.low);
                     res.set_header("X-Map-Low", text);
                     std::snprintf(text, sizeof text, "%.6g", map.high);
                     res.set_header("X-Map-High", text);
                     res.set_header("X-Map-Scale", variance ? "log" : "linear");
                     if (variance) res.set_header("X-Map-Source", maps.variance_source);
                     send_png(res, map.image);
                 });
    }
    http.Post(std::string(kJob) + "/cancel",
              [this, authorized](const httplib::Request& req, httplib::Response& res) {
                  if (!authorized(req, res)) return;
                  v1::Job job;
                  if (grpc::Status st = manager_.cancel(req.matches[1], &job); !st.ok())
                      return send_error(res, st);
                  Log("info", "http_cancel").kv("job", std::string(req.matches[1]));
                  send_message(res, job);
              });
    http.Post(std::string(kJob) + "/priority", [this, authorized](const httplib::Request& req,
                                                                  httplib::Response& res) {
        if (!authorized(req, res)) return;
        const std::string v = req.get_param_value("value");
        int priority = 0;
        try {
            size_t used = 0;
            const long p = std::stol(v, &used);
            if (used != v.size() || p < -1000000 || p > 1000000) throw std::out_of_range(v);
            priority = int(p);
        } catch (const std::exception&) {
            return send_error(res, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                                "?value= must be an integer in "
                                                "[-1000000, 1000000]"));
        }
        v1::Job job;
        if (grpc::Status st = manager_.set_priority(req.matches[1], priority, &job); !st.ok())
            return send_error(res, st);
        send_message(res, job);
    });
}

HttpServer::~HttpServer() {
    stop();
}

int HttpServer::start(const std::string& host, int port) {
    int bound = port;
    if (port == 0)
        bound = http_->bind_to_any_port(host);
    else if (!http_->bind_to_port(host, port))
        bound = 0;
    if (bound <= 0) return 0;
    thread_ = std::thread([this] { http_->listen_after_bind(); });
    return bound;
}

void HttpServer::stop() {
    if (http_) http_->stop();
    if (thread_.joinable()) thread_.join();
}

}  // namespace render::server
