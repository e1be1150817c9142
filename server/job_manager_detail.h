#pragma once

// Small helpers shared by the job manager's source files (job_manager*.cpp); not an API.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdint>
#include <exception>
#include <random>
#include <string>

#include "core/render/render_options.h"
#include "core/util/log.h"
#include "render.pb.h"

namespace render::server::detail {

inline int64_t unix_ms() {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

// The settings a job renders with (job_manager.cpp): its stored options are complete.
RenderSettings job_settings(const ::render::v1::SubmitJobRequest& request);

inline std::string random_hex(int digits) {
    static thread_local std::mt19937_64 rng{std::random_device{}()};
    static const char* hex = "0123456789abcdef";
    std::string out;
    for (int i = 0; i < digits; ++i) out.push_back(hex[rng() & 15]);
    return out;
}

inline grpc::Status invalid(const std::string& message) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, message);
}

// NOT_FOUND for a job id (cut to 80 characters: it is the caller's text).
inline grpc::Status job_not_found(const std::string& job_id) {
    return grpc::Status(grpc::StatusCode::NOT_FOUND,
                        "job \"" + job_id.substr(0, 80) + "\" not found");
}

// NOT_FOUND for a frame index past a job's frames.
inline grpc::Status frame_not_found(const std::string& job_id, uint32_t index, size_t frames) {
    return grpc::Status(grpc::StatusCode::NOT_FOUND, "job " + job_id + " has no frame " +
                                                         std::to_string(index) + " (" +
                                                         std::to_string(frames) + " frames)");
}

// The job store is the record of what survives a restart; a failed write is logged and the
// in-memory state goes on (the next checkpoint or restart reconciles it).
template <typename Write>
void store_or_log(const char* key, const std::string& id, Write&& write) {
    try {
        write();
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv(key, id).kv("error", e.what());
    }
}

}  // namespace render::server::detail
