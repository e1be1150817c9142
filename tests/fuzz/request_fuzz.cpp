// Fuzz target: the requests the server accepts, in-process. The first byte picks a message
// type, the rest is parsed as that protobuf message (ParseFromArray) and handed to the same
// entry point the gRPC server calls: the JobService and WorkerService unary methods (with a
// bare ServerContext, no token configured) and, for the streamed calls, the JobManager checks
// behind them (check_report, result_file). One JobManager with a store in a temporary folder
// lives for the whole run, so jobs, workers and leases accumulate as on a real server; its
// asset store holds one small scene (kSceneXml, also in make_corpus.py, whose seeds submit it),
// so that submitted jobs can load and be leased. A bad request must give a status, never a
// crash, an exception or a hang.

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "core/util/sha256.h"
#include "render.pb.h"
#include "server/auth.h"
#include "server/job_manager.h"
#include "server/job_service.h"
#include "server/validation.h"
#include "server/worker_service.h"
#include "tests/fuzz/fuzz_files.h"

namespace {

using namespace render::server;
namespace v1 = render::v1;

// A sphere lit by a point light on a 16x16 film.
constexpr const char* kSceneXml =
    "<scene version=\"3.0.0\">\n"
    "  <sensor type=\"perspective\">\n"
    "    <transform name=\"to_world\"><lookat origin=\"0,0,5\" target=\"0,0,0\" "
    "up=\"0,1,0\"/></transform>\n"
    "    <film type=\"hdrfilm\"><integer name=\"width\" value=\"16\"/>"
    "<integer name=\"height\" value=\"16\"/></film>\n"
    "  </sensor>\n"
    "  <shape type=\"sphere\"/>\n"
    "  <emitter type=\"point\"><point name=\"position\" value=\"0,0,3\"/></emitter>\n"
    "</scene>\n";

struct Server {
    Server()
        : manager(ServerOptions{.store = render::fuzz::fuzz_folder() / "store"}),
          auth(""),
          jobs(manager, auth, stopping),
          workers(manager, auth) {
        const std::string scene = kSceneXml;
        const std::string sha = render::sha256_hex(scene);
        AssetStore::Upload upload(manager.assets(), sha, scene.size());
        if (!upload.write(scene).empty() || !upload.commit().empty()) std::abort();
        manager.asset_added(sha, scene.size());
    }
    JobManager manager;
    Auth auth;
    std::atomic<bool> stopping{false};
    JobServiceImpl jobs;
    WorkerServiceImpl workers;
};

Server& server() {
    static Server* s = new Server();  // never destroyed: the process ends with the fuzzer
    return *s;
}

// Prints a call's status when RENDER_FUZZ_VERBOSE is set (to see what the seeds reach).
void note(const char* call, const grpc::Status& status) {
    static const bool verbose = std::getenv("RENDER_FUZZ_VERBOSE") != nullptr;
    if (verbose)
        std::fprintf(stderr, "  %s: %d %s\n", call, int(status.error_code()),
                     status.error_message().c_str());
}

template <typename Message>
bool parse(Message& m, const uint8_t* data, size_t size) {
    return m.ParseFromArray(data, int(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    if (size < 1 || size > (1 << 20)) return 0;
    Server& s = server();
    const uint8_t kind = data[0];
    ++data, --size;
    grpc::ServerContext context;
    switch (kind % 12) {
        case 0: {
            v1::SubmitJobRequest r;
            if (!parse(r, data, size)) return 0;
            note("check_submit_request", check_submit_request(r));
            v1::Job reply;
            note("SubmitJob", s.jobs.SubmitJob(&context, &r, &reply));
            break;
        }
        case 1: {
            v1::GetJobRequest r;
            if (!parse(r, data, size)) return 0;
            v1::Job reply;
            note("GetJob", s.jobs.GetJob(&context, &r, &reply));
            break;
        }
        case 2: {
            v1::CancelJobRequest r;
            if (!parse(r, data, size)) return 0;
            v1::Job reply;
            note("CancelJob", s.jobs.CancelJob(&context, &r, &reply));
            break;
        }
        case 3: {
            v1::HasAssetsRequest r;
            if (!parse(r, data, size)) return 0;
            v1::HasAssetsReply reply;
            note("HasAssets", s.jobs.HasAssets(&context, &r, &reply));
            break;
        }
        case 4: {
            v1::FetchResultRequest r;
            if (!parse(r, data, size)) return 0;
            std::filesystem::path file;
            bool temporary = false;
            const grpc::Status status = s.manager.result_file(r, &file, &temporary);
            note("result_file", status);
            if (status.ok() && temporary) {
                std::error_code ec;
                std::filesystem::remove(file, ec);
            }
            break;
        }
        case 5: {
            v1::RegisterWorkerRequest r;
            if (!parse(r, data, size)) return 0;
            v1::RegisterWorkerReply reply;
            note("RegisterWorker", s.workers.RegisterWorker(&context, &r, &reply));
            break;
        }
        case 6: {
            v1::LeaseRequest r;
            if (!parse(r, data, size)) return 0;
            v1::LeaseReply reply;
            note("Lease", s.workers.Lease(&context, &r, &reply));
            break;
        }
        case 7: {
            v1::HeartbeatRequest r;
            if (!parse(r, data, size)) return 0;
            v1::HeartbeatReply reply;
            note("Heartbeat", s.workers.Heartbeat(&context, &r, &reply));
            break;
        }
        case 8: {
            v1::ReportHeader r;
            if (!parse(r, data, size)) return 0;
            size_t values = 0, layers = 0, exact_words = 0;
            bool drop = false;
            note("check_report", s.manager.check_report(r, &values, &layers, &exact_words, &drop));
            break;
        }
        case 10: {
            v1::DeleteJobRequest r;
            if (!parse(r, data, size)) return 0;
            v1::DeleteJobReply reply;
            note("DeleteJob", s.jobs.DeleteJob(&context, &r, &reply));
            break;
        }
        case 11: {
            v1::FetchMaskRequest r;
            if (!parse(r, data, size)) return 0;
            std::string packed;
            note("fetch_mask", s.manager.fetch_mask(r, &packed));
            break;
        }
        default: {
            v1::ClusterStatusRequest r;
            if (!parse(r, data, size)) return 0;
            v1::ClusterStatusReply reply;
            note("ClusterStatus", s.jobs.ClusterStatus(&context, &r, &reply));
            s.manager.tick();
            break;
        }
    }
    return 0;
}
