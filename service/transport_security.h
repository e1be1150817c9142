#pragma once

// Transport security of the render service (docs/guide/service.md, "Transport security"): TLS
// credentials for the server (--tls-cert/--tls-key) and for its clients and workers
// (--tls-ca, --tls-server-name), and the rule for a bearer token over plaintext:
//
//   * server: a token without TLS needs --insecure, and --insecure is accepted on a loopback
//     --listen address only; --http (whose /api/ takes the token over plain HTTP) must be on a
//     loopback address when the server has a token.
//   * client and worker: a token is never sent over plaintext to a non-loopback address.
//
// The check_* functions return "" when the combination is allowed, else the error message,
// which names the flag to use.

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>
#include <string_view>

namespace render::service {

// True for addresses that never leave the machine: 127.0.0.0/8, ::1 (also IPv4-mapped
// ::ffff:127.x.x.x), "localhost", and Unix domain sockets (unix:..., unix-abstract:...).
// Takes HOST:PORT, [IPV6]:PORT, a bare host, and gRPC target forms (dns:///HOST:PORT,
// ipv4:A:P,B:P and ipv6:[A]:P lists: loopback only if every address is). Anything that cannot
// be parsed, and wildcard addresses such as 0.0.0.0 and [::], are not loopback.
bool is_loopback_address(std::string_view address);

// The server's plaintext rule: `listen` is the --listen address.
std::string check_server_transport(const std::string& listen, bool tls, bool has_token,
                                   bool insecure);
// `http` is the --http address (empty: none); /metrics alone (--metrics) takes no token.
std::string check_http_transport(const std::string& http, bool has_token);
// The client's and worker's rule: `server` is the address it connects to.
std::string check_client_transport(const std::string& server, bool tls, bool has_token);

// The contents of a PEM file given with `flag`; throws std::runtime_error naming the flag and
// the file when it cannot be read or holds no PEM block of the expected kind
// ("CERTIFICATE" or "PRIVATE KEY", matched as the end of the BEGIN line's label).
std::string read_pem_file(const std::string& flag, const std::string& path,
                          const std::string& kind);

// What a client or worker needs to open a TLS channel; tls == false: plaintext.
struct ClientTls {
    bool tls = false;
    std::string root_certs;   // PEM: the CA(s) the server's certificate must chain to
    std::string server_name;  // non-empty: check the certificate for this name, not the host
};

// Reads --tls-ca (or env RENDER_TLS_CA) and --tls-server-name (or RENDER_TLS_SERVER_NAME);
// empty ca_file and no environment: plaintext. Throws like read_pem_file.
ClientTls client_tls_from(const std::string& ca_file, const std::string& server_name);

std::shared_ptr<grpc::ChannelCredentials> channel_credentials(const ClientTls& tls);

// The flag value, else the environment variable, else "".
std::string flag_or_env(const std::string& flag_value, const char* variable);

}  // namespace render::service
