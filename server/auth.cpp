#include "server/auth.h"

namespace render::server {

namespace {
// Compares in time independent of where the strings differ.
bool same(std::string_view a, std::string_view b) {
    unsigned char diff = a.size() == b.size() ? 0 : 1;
    for (size_t i = 0; i < a.size(); ++i) diff |= (unsigned char)(a[i] ^ b[i % (b.size() + 1)]);
    return diff == 0;
}
}  // namespace

grpc::Status Auth::check(const grpc::ServerContext* context) const {
    if (token_.empty()) return grpc::Status::OK;
    const auto& metadata = context->client_metadata();
    auto it = metadata.find("authorization");
    if (it == metadata.end()) return check_header(false, {});
    return check_header(true, std::string_view(it->second.data(), it->second.size()));
}

grpc::Status Auth::check_header(bool present, std::string_view value) const {
    if (token_.empty()) return grpc::Status::OK;
    if (!present)
        return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                            "missing \"authorization: Bearer <token>\" metadata");
    constexpr std::string_view prefix = "Bearer ";
    if (value.substr(0, prefix.size()) != prefix || !same(value.substr(prefix.size()), token_))
        return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "invalid token");
    return grpc::Status::OK;
}

}  // namespace render::server
