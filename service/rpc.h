#pragma once

// gRPC plumbing shared by the worker and the client (header-only): the channel with a short
// reconnect backoff, the bearer token, deadlines and readable status codes.
// No OpenImageIO header may be included next to this one (DEPENDENCIES.md, trap 2).

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>

#include "service/transport_security.h"

namespace render::service {

// Largest payload of one streamed chunk (assets, report values, results).
constexpr size_t kMaxChunkBytes = size_t(1) << 20;

// A channel to `address`: plaintext, or TLS with `tls` (service/transport_security.h).
inline std::shared_ptr<grpc::Channel> make_channel(const std::string& address,
                                                   const ClientTls& tls = {}) {
    grpc::ChannelArguments args;
    // gRPC's own reconnect backoff grows to 2 minutes by default; a restarted server should be
    // found again within seconds.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 5000);
    if (tls.tls && !tls.server_name.empty()) args.SetSslTargetNameOverride(tls.server_name);
    return grpc::CreateCustomChannel(address, channel_credentials(tls), args);
}

// Sets the bearer token (if any) and a deadline (if timeout_seconds > 0) on a call.
inline void prepare_context(grpc::ClientContext& context, const std::string& token,
                            double timeout_seconds) {
    if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
    if (timeout_seconds > 0)
        context.set_deadline(std::chrono::system_clock::now() +
                             std::chrono::milliseconds(int64_t(timeout_seconds * 1000)));
}

inline const char* status_code_name(grpc::StatusCode code) {
    switch (code) {
        case grpc::StatusCode::OK:
            return "OK";
        case grpc::StatusCode::CANCELLED:
            return "CANCELLED";
        case grpc::StatusCode::UNKNOWN:
            return "UNKNOWN";
        case grpc::StatusCode::INVALID_ARGUMENT:
            return "INVALID_ARGUMENT";
        case grpc::StatusCode::DEADLINE_EXCEEDED:
            return "DEADLINE_EXCEEDED";
        case grpc::StatusCode::NOT_FOUND:
            return "NOT_FOUND";
        case grpc::StatusCode::ALREADY_EXISTS:
            return "ALREADY_EXISTS";
        case grpc::StatusCode::PERMISSION_DENIED:
            return "PERMISSION_DENIED";
        case grpc::StatusCode::UNAUTHENTICATED:
            return "UNAUTHENTICATED";
        case grpc::StatusCode::RESOURCE_EXHAUSTED:
            return "RESOURCE_EXHAUSTED";
        case grpc::StatusCode::FAILED_PRECONDITION:
            return "FAILED_PRECONDITION";
        case grpc::StatusCode::ABORTED:
            return "ABORTED";
        case grpc::StatusCode::OUT_OF_RANGE:
            return "OUT_OF_RANGE";
        case grpc::StatusCode::UNIMPLEMENTED:
            return "UNIMPLEMENTED";
        case grpc::StatusCode::INTERNAL:
            return "INTERNAL";
        case grpc::StatusCode::UNAVAILABLE:
            return "UNAVAILABLE";
        case grpc::StatusCode::DATA_LOSS:
            return "DATA_LOSS";
        default:
            return "UNKNOWN_CODE";
    }
}

inline std::string describe(const grpc::Status& status) {
    return std::string(status_code_name(status.error_code())) + ": " + status.error_message();
}

// The token from the command line, else the environment's RENDER_TOKEN.
inline std::string token_or_env(const std::string& flag_value) {
    if (!flag_value.empty()) return flag_value;
    const char* env = std::getenv("RENDER_TOKEN");
    return env ? env : "";
}

}  // namespace render::service
