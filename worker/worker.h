#pragma once

// The worker loop: register, lease a range of iterations, fetch the scene's assets, render
// the range with render_iterations while heartbeating, and stream the sums back in the
// background while the next lease renders (one report in flight at most).

#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/scene.h"
#include "render.grpc.pb.h"
#include "service/transport_security.h"
#include "worker/asset_cache.h"
#include "worker/background_report.h"
#include "worker/render_fault.h"

namespace render::service {

// 8 GiB: under the 10 Gi emptyDir of deploy/kubernetes/worker-deployment.yaml.
inline constexpr uint64_t kDefaultCacheMaxBytes = uint64_t(8) << 30;

struct WorkerOptions {
    // HOST:PORT of each server, in order of preference: the worker uses one at a time and
    // moves to the next when it cannot be reached (docs/guide/service.md, "Several servers").
    std::vector<std::string> servers;
    int threads = 0;  // 0 = all cores
    std::string token;
    ClientTls tls;  // plaintext unless tls.tls
    std::filesystem::path cache_dir;
    // The bound on the asset cache's size (0: none): least recently used job folders and
    // assets go first; the job in use never (worker/asset_cache.h).
    uint64_t cache_max_bytes = kDefaultCacheMaxBytes;
    // The memory a job's scene and film may take (0: the machine's available memory when the
    // scene is loaded). A scene estimated to need more fails its job with that message.
    uint64_t max_memory = 0;
    // Tests only (--test-render-fault): the renderer fails every lease this way
    // (worker/render_fault.h). None by default.
    RenderFault test_render_fault;
};

// Set by the signal handler: 1 = finish the current range and exit, 2+ = give up at once.
extern std::atomic<int> g_stop_requests;

class Worker {
  public:
    explicit Worker(WorkerOptions options);
    // Runs until a stop is requested. Returns the process exit code (0, or 1 when the server
    // refuses the token).
    int run();

  private:
    enum class Outcome { Reported, Dropped, Cancelled, Failed };

    // One server of the list: the channel, and this worker's id there (empty until
    // registered). A lease's heartbeats, report and failure go to the server that granted it
    // (only it knows the lease), whatever server the worker has moved to since.
    struct ServerLink {
        std::string address;
        std::shared_ptr<grpc::Channel> channel;
        std::unique_ptr<v1::WorkerService::Stub> stub;
        std::string worker_id;
    };
    // Connects to options_.servers[index] (not yet registered).
    std::shared_ptr<ServerLink> link_to(size_t index) const;
    // Moves to the next server of the list (a no-op with one), after `why` failed.
    void next_server(const char* why);

    bool register_worker();
    // Renders the lease and hands its sums to report_in_flight_ (Reported: handed over).
    Outcome process(const v1::Lease& lease);
    const Scene& scene_for(const v1::Lease& lease, const std::filesystem::path& scene_file);
    grpc::Status fetch_asset(const std::string& sha256,
                             const std::function<void(const std::string&)>& sink);
    // The mask of the lease's adaptive round (one entry per pixel), the one kept if it is the
    // same round's, else fetched (FetchMask) and checked against the lease's hash and active
    // count; null (and `error` set) when it cannot be had.
    const std::vector<uint8_t>* mask_for(const v1::Lease& lease, size_t pixels, std::string* error);
    // false: the lease was cancelled. `rates`: the lease's render rates so far, if measured.
    bool heartbeat(const std::string& lease_id, const v1::WorkerRates* rates);
    // Tells the server that this worker cannot render the lease (best effort: if the server
    // does not hear it, the lease expires as before).
    // memory_needed/memory_limit: set for a refusal for memory (MemoryLimitExceeded), which the
    // server does not count toward failing the job; report_undelivered: the range was rendered
    // but its report could not be delivered (LeaseFailure.report_undelivered).
    void report_failure(const ServerLink& link, const std::string& lease_id,
                        const std::string& error, uint64_t memory_needed = 0,
                        uint64_t memory_limit = 0, bool report_undelivered = false);
    // Sends a finished lease's sums, retrying while the lease may still be alive (runs on
    // report_in_flight_'s thread).
    Outcome report(const ServerLink& link, const v1::Lease& lease,
                   const struct RangeResult& result);
    // Sleeps up to `seconds`, waking early when a stop is requested.
    static void nap(double seconds);

    WorkerOptions options_;
    size_t server_index_ = 0;
    // The server in use (the main thread's; a report in flight keeps its own).
    std::shared_ptr<ServerLink> link_;
    AssetCache cache_;
    double heartbeat_seconds_ = 2.0;
    bool token_rejected_ = false;

    std::string scene_key_;
    std::unique_ptr<Scene> scene_;
    // What the scene and film were estimated to need when scene_ was loaded (the memory
    // budget's charges), to which each lease adds its algorithm's working memory.
    uint64_t scene_memory_ = 0;

    // The last adaptive round's mask and its key (job, frame, round, hash).
    std::string mask_key_;
    std::vector<uint8_t> mask_;

    // The lease of the report in flight and the server that granted it (main thread only):
    // heartbeaten while the worker idles (Worker::run).
    std::string in_flight_lease_;
    std::shared_ptr<ServerLink> in_flight_link_;

    // Last: destroyed first, waiting for the report in flight while the stub is alive.
    BackgroundReport report_in_flight_;
};

}  // namespace render::service
