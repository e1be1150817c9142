// The transport-security rule (service/transport_security.h): which addresses are loopback,
// when a token may travel in clear, and the PEM file checks.

#include "service/transport_security.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace render::service {
namespace {

TEST(TransportSecurity, LoopbackAddresses) {
    for (const char* a :
         {"127.0.0.1:50051", "127.0.0.1:0", "127.1.2.3:80", "localhost:50051", "LOCALHOST:1",
          "localhost", "127.0.0.1", "[::1]:50051", "[::1]", "::1", "[::ffff:127.0.0.1]:5",
          "dns:///localhost:50051", "dns:127.0.0.1:50051", "dns://8.8.8.8/127.0.0.1:1",
          "ipv4:127.0.0.1:1,127.0.0.2:2", "ipv6:[::1]:50051", "unix:/tmp/render.sock",
          "unix:///tmp/render.sock", "unix-abstract:render"})
        EXPECT_TRUE(is_loopback_address(a)) << a;
}

TEST(TransportSecurity, NonLoopbackAddresses) {
    for (const char* a : {"0.0.0.0:50051",
                          "[::]:50051",
                          "::",
                          ":50051",
                          "",
                          "10.0.0.5:50051",
                          "128.0.0.1:50051",
                          "192.168.1.2",
                          "render-server:50051",
                          "localhost.evil.com:1",
                          "127.0.0.1.nip.io:50051",
                          "[::2]:50051",
                          "[::ffff:10.0.0.1]:5",
                          "[::1:50051",
                          "[::1]x",
                          "ipv4:127.0.0.1:1,10.0.0.1:2",
                          "ipv4:",
                          "dns:///render-server:50051",
                          "dns://8.8.8.8",
                          "example.com:443",
                          "1.2.3.4:127"})
        EXPECT_FALSE(is_loopback_address(a)) << a;
}

TEST(TransportSecurity, ServerRule) {
    // TLS: a token is fine anywhere.
    EXPECT_EQ(check_server_transport("0.0.0.0:50051", true, true, false), "");
    EXPECT_EQ(check_server_transport("127.0.0.1:0", true, false, false), "");
    // Without a token there is nothing to protect: plaintext anywhere.
    EXPECT_EQ(check_server_transport("0.0.0.0:50051", false, false, false), "");
    EXPECT_EQ(check_server_transport("127.0.0.1:0", false, false, false), "");
    // A token in clear needs --insecure, which needs a loopback address.
    EXPECT_EQ(check_server_transport("127.0.0.1:0", false, true, true), "");
    EXPECT_EQ(check_server_transport("[::1]:0", false, true, true), "");
    const std::string loopback = check_server_transport("127.0.0.1:0", false, true, false);
    EXPECT_NE(loopback.find("--tls-cert FILE --tls-key FILE"), std::string::npos) << loopback;
    EXPECT_NE(loopback.find("--insecure"), std::string::npos) << loopback;
    const std::string open = check_server_transport("0.0.0.0:50051", false, true, false);
    EXPECT_NE(open.find("--tls-cert FILE --tls-key FILE"), std::string::npos) << open;
    EXPECT_NE(open.find("0.0.0.0:50051 is not one"), std::string::npos) << open;
    // --insecure off loopback is refused, token or not.
    for (bool token : {false, true}) {
        const std::string e = check_server_transport("10.0.0.5:50051", false, token, true);
        EXPECT_NE(e.find("--insecure is only accepted on a loopback --listen address"),
                  std::string::npos)
            << e;
    }
    // --insecure with TLS is a contradiction.
    EXPECT_NE(check_server_transport("127.0.0.1:0", true, true, true).find("contradicts"),
              std::string::npos);
}

TEST(TransportSecurity, HttpRule) {
    EXPECT_EQ(check_http_transport("", true), "");
    EXPECT_EQ(check_http_transport("0.0.0.0:8080", false), "");
    EXPECT_EQ(check_http_transport("127.0.0.1:0", true), "");
    const std::string e = check_http_transport("0.0.0.0:8080", true);
    EXPECT_NE(e.find("--http 0.0.0.0:8080"), std::string::npos) << e;
    EXPECT_NE(e.find("loopback"), std::string::npos) << e;
}

TEST(TransportSecurity, ClientRule) {
    EXPECT_EQ(check_client_transport("render-server:50051", true, true), "");
    EXPECT_EQ(check_client_transport("render-server:50051", false, false), "");
    EXPECT_EQ(check_client_transport("127.0.0.1:50051", false, true), "");
    EXPECT_EQ(check_client_transport("localhost:50051", false, true), "");
    const std::string e = check_client_transport("10.0.0.5:50051", false, true);
    EXPECT_NE(e.find("10.0.0.5:50051"), std::string::npos) << e;
    EXPECT_NE(e.find("--tls-ca FILE"), std::string::npos) << e;
}

class PemFiles : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("render-tls-test-" + std::to_string(getpid()));
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string write(const std::string& name, const std::string& text) {
        const auto path = dir_ / name;
        std::ofstream(path) << text;
        return path.string();
    }
    std::string error_of(const std::string& flag, const std::string& path,
                         const std::string& kind) {
        try {
            read_pem_file(flag, path, kind);
        } catch (const std::runtime_error& e) {
            return e.what();
        }
        return "";
    }
    std::filesystem::path dir_;
};

TEST_F(PemFiles, ReadsMatchingBlocks) {
    const std::string cert = "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n";
    EXPECT_EQ(read_pem_file("--tls-ca", write("ca.pem", cert), "CERTIFICATE"), cert);
    for (const char* label : {"PRIVATE KEY", "RSA PRIVATE KEY", "EC PRIVATE KEY"}) {
        const std::string key =
            std::string("-----BEGIN ") + label + "-----\nMIIE\n-----END " + label + "-----\n";
        EXPECT_EQ(read_pem_file("--tls-key", write("key.pem", key), "PRIVATE KEY"), key);
    }
}

TEST_F(PemFiles, ErrorsNameTheFlagAndTheFile) {
    const std::string missing = (dir_ / "nope.pem").string();
    const std::string e1 = error_of("--tls-cert", missing, "CERTIFICATE");
    EXPECT_NE(e1.find("--tls-cert " + missing + ": cannot read"), std::string::npos) << e1;
    EXPECT_NE(e1.find("No such file"), std::string::npos) << e1;

    const std::string key = write("key.pem", "-----BEGIN PRIVATE KEY-----\nx\n");
    const std::string e2 = error_of("--tls-cert", key, "CERTIFICATE");
    EXPECT_NE(e2.find("--tls-cert " + key + ": not a PEM file with a CERTIFICATE"),
              std::string::npos)
        << e2;
    const std::string junk = write("junk.pem", "hello");
    EXPECT_NE(error_of("--tls-key", junk, "PRIVATE KEY").find("not a PEM file"), std::string::npos);
    // A folder is not a file.
    EXPECT_NE(error_of("--tls-ca", dir_.string(), "CERTIFICATE").find("--tls-ca"),
              std::string::npos);
}

TEST_F(PemFiles, ClientTlsFromFlagsAndEnvironment) {
    unsetenv("RENDER_TLS_CA");
    unsetenv("RENDER_TLS_SERVER_NAME");
    EXPECT_FALSE(client_tls_from("", "").tls);
    EXPECT_THROW(client_tls_from("", "render-server"), std::runtime_error);
    const std::string ca =
        write("ca.pem", "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n");
    const ClientTls a = client_tls_from(ca, "render-server");
    EXPECT_TRUE(a.tls);
    EXPECT_EQ(a.server_name, "render-server");
    EXPECT_NE(a.root_certs.find("MIIB"), std::string::npos);
    setenv("RENDER_TLS_CA", ca.c_str(), 1);
    EXPECT_TRUE(client_tls_from("", "").tls);
    setenv("RENDER_TLS_CA", (dir_ / "missing.pem").c_str(), 1);
    EXPECT_THROW(client_tls_from("", ""), std::runtime_error);
    EXPECT_TRUE(client_tls_from(ca, "").tls);  // the flag wins over the environment
    unsetenv("RENDER_TLS_CA");
}

}  // namespace
}  // namespace render::service
