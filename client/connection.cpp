#include "client/connection.h"

#include <cstdio>

namespace render::service {

std::optional<Connection> connect_to_server(const std::string& server, const std::string& token,
                                            const std::string& tls_ca,
                                            const std::string& tls_server_name) {
    Connection c;
    c.address = server;
    c.token = token_or_env(token);
    ClientTls tls;
    try {
        tls = client_tls_from(tls_ca, tls_server_name);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "client: %s\n", e.what());
        return std::nullopt;
    }
    if (const std::string problem = check_client_transport(server, tls.tls, !c.token.empty());
        !problem.empty()) {
        std::fprintf(stderr, "client: %s\n", problem.c_str());
        return std::nullopt;
    }
    c.stub = v1::JobService::NewStub(make_channel(server, tls));
    return c;
}

bool tls_used(const std::string& tls_ca_flag) {
    return !flag_or_env(tls_ca_flag, "RENDER_TLS_CA").empty();
}

std::string connection_hint(const grpc::Status& status, bool tls) {
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE) return "";
    return tls ? "\nclient: with --tls-ca the server must serve TLS (--tls-cert/--tls-key) with a "
                 "certificate signed by that CA for the host of --server (or for "
                 "--tls-server-name)"
               : "\nclient: if the server serves TLS (--tls-cert/--tls-key), give --tls-ca FILE";
}

v1::Job get_job(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::GetJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    grpc::Status status = c.stub->GetJob(&context, request, &job);
    if (!status.ok()) throw RpcFailure("GetJob", status);
    return job;
}

}  // namespace render::service
