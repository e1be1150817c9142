#pragma once

// Optional bearer-token authentication: with a token configured, every call must carry the
// metadata `authorization: Bearer <token>`, otherwise it gets UNAUTHENTICATED.

#include <grpcpp/grpcpp.h>

#include <string>

namespace render::server {

class Auth {
  public:
    explicit Auth(std::string token) : token_(std::move(token)) {}
    bool enabled() const { return !token_.empty(); }
    grpc::Status check(const grpc::ServerContext* context) const;
    // The same rule for an `authorization` header's value (the HTTP API); `present` false when
    // the request has no such header.
    grpc::Status check_header(bool present, std::string_view value) const;

  private:
    std::string token_;
};

}  // namespace render::server
