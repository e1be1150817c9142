#include "service/transport_security.h"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace render::service {

namespace {

std::string lower(std::string_view s) {
    std::string out(s);
    std::transform(out.begin(), out.end(), out.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return out;
}

bool starts_with(std::string_view s, std::string_view prefix) {
    return s.substr(0, prefix.size()) == prefix;
}

bool is_loopback_host(std::string host) {
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    if (host.empty()) return false;  // ":50051" listens on every interface
    if (lower(host) == "localhost") return true;
    unsigned char v4[4];
    if (inet_pton(AF_INET, host.c_str(), v4) == 1) return v4[0] == 127;
    unsigned char v6[16];
    if (inet_pton(AF_INET6, host.c_str(), v6) == 1) {
        static const unsigned char loopback[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
        static const unsigned char mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
        if (std::memcmp(v6, loopback, 16) == 0) return true;
        return std::memcmp(v6, mapped, 12) == 0 && v6[12] == 127;
    }
    return false;
}

// The host of HOST:PORT, [IPV6]:PORT, HOST or a bare IPv6 address; "" if malformed.
std::string host_of(std::string_view address) {
    if (starts_with(address, "[")) {
        const size_t close = address.find(']');
        if (close == std::string_view::npos) return "";
        const std::string_view rest = address.substr(close + 1);
        if (!rest.empty() && rest.front() != ':') return "";
        return std::string(address.substr(0, close + 1));
    }
    const size_t first = address.find(':');
    if (first == std::string_view::npos) return std::string(address);
    if (address.find(':', first + 1) == std::string_view::npos)
        return std::string(address.substr(0, first));
    return std::string(address);  // several colons without brackets: a bare IPv6 address
}

std::vector<std::string_view> split_commas(std::string_view s) {
    std::vector<std::string_view> parts;
    for (size_t start = 0;;) {
        const size_t comma = s.find(',', start);
        parts.push_back(s.substr(start, comma - start));
        if (comma == std::string_view::npos) return parts;
        start = comma + 1;
    }
}

}  // namespace

bool is_loopback_address(std::string_view address) {
    const std::string scheme = lower(address.substr(0, address.find(':') + 1));
    if (scheme == "unix:" || scheme == "unix-abstract:") return true;
    if (scheme == "ipv4:" || scheme == "ipv6:") {
        const std::string_view list = address.substr(scheme.size());
        if (list.empty()) return false;
        for (std::string_view one : split_commas(list))
            if (!is_loopback_host(host_of(one))) return false;
        return true;
    }
    if (scheme == "dns:") {
        address.remove_prefix(4);
        if (starts_with(address, "//")) {  // dns://[AUTHORITY]/HOST:PORT
            const size_t slash = address.find('/', 2);
            if (slash == std::string_view::npos) return false;
            address.remove_prefix(slash + 1);
        }
    }
    return is_loopback_host(host_of(address));
}

std::string check_server_transport(const std::string& listen, bool tls, bool has_token,
                                   bool insecure) {
    if (tls && insecure)
        return "--insecure contradicts --tls-cert/--tls-key: give one or the other";
    if (tls) return "";
    const bool loopback = is_loopback_address(listen);
    if (insecure && !loopback)
        return "--insecure is only accepted on a loopback --listen address (127.0.0.1, [::1], "
               "localhost), not " +
               listen + ": give --tls-cert FILE --tls-key FILE to serve TLS";
    if (has_token && !insecure)
        return "a token over plaintext: give --tls-cert FILE --tls-key FILE to serve TLS" +
               std::string(loopback ? ", or --insecure to accept the token in clear on this "
                                      "loopback address"
                                    : " (--insecure is only accepted on a loopback --listen "
                                      "address, and " +
                                          listen + " is not one)");
    return "";
}

std::string check_http_transport(const std::string& http, bool has_token) {
    if (http.empty() || !has_token || is_loopback_address(http)) return "";
    return "--http " + http +
           ": the dashboard's /api/ takes the token over plain HTTP, so with a token --http "
           "must be a loopback address (e.g. --http 127.0.0.1:8080, reached through an SSH "
           "tunnel or kubectl port-forward); --metrics needs no token and may listen anywhere";
}

std::string check_client_transport(const std::string& server, bool tls, bool has_token) {
    if (tls || !has_token || is_loopback_address(server)) return "";
    return "refusing to send the token in clear to " + server +
           ", which is not a loopback address: give --tls-ca FILE (env RENDER_TLS_CA), the CA "
           "that signed the server's --tls-cert";
}

std::string read_pem_file(const std::string& flag, const std::string& path,
                          const std::string& kind) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        const int error = errno;
        throw std::runtime_error(
            flag + " " + path + ": cannot read: " + (error ? std::strerror(error) : "cannot open"));
    }
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw std::runtime_error(flag + " " + path + ": cannot read: I/O error");
    const std::string pem = text.str();
    // A BEGIN line whose label ends with `kind`: "CERTIFICATE", "PRIVATE KEY", "RSA PRIVATE
    // KEY", "EC PRIVATE KEY".
    for (size_t at = pem.find("-----BEGIN "); at != std::string::npos;
         at = pem.find("-----BEGIN ", at + 1)) {
        const size_t end = pem.find("-----", at + 11);
        if (end == std::string::npos) break;
        const std::string label = pem.substr(at + 11, end - at - 11);
        if (label.size() >= kind.size() &&
            label.compare(label.size() - kind.size(), kind.size(), kind) == 0)
            return pem;
    }
    throw std::runtime_error(flag + " " + path + ": not a PEM file with a " + kind +
                             " (no \"-----BEGIN ..." + kind + "-----\" line)");
}

std::string flag_or_env(const std::string& flag_value, const char* variable) {
    if (!flag_value.empty()) return flag_value;
    const char* env = std::getenv(variable);
    return env ? env : "";
}

ClientTls client_tls_from(const std::string& ca_file, const std::string& server_name) {
    ClientTls tls;
    const std::string ca = flag_or_env(ca_file, "RENDER_TLS_CA");
    tls.server_name = flag_or_env(server_name, "RENDER_TLS_SERVER_NAME");
    if (ca.empty()) {
        if (!tls.server_name.empty())
            throw std::runtime_error("--tls-server-name " + tls.server_name +
                                     " without --tls-ca: the name is only checked over TLS");
        return tls;
    }
    tls.tls = true;
    tls.root_certs = read_pem_file("--tls-ca", ca, "CERTIFICATE");
    return tls;
}

std::shared_ptr<grpc::ChannelCredentials> channel_credentials(const ClientTls& tls) {
    if (!tls.tls) return grpc::InsecureChannelCredentials();
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = tls.root_certs;
    return grpc::SslCredentials(options);
}

}  // namespace render::service
