#include "worker/worker.h"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>

#include "core/base/memory_budget.h"
#include "core/render/algorithms.h"
#include "core/render/iteration_memory.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/log.h"
#include "core/util/sha256.h"
#include "service/bundle_paths.h"
#include "service/idle_poll.h"
#include "service/mask_bits.h"
#include "service/request_options.h"
#include "service/rpc.h"

namespace render::service {

static_assert(std::endian::native == std::endian::little,
              "reports carry little-endian float64 values");

std::atomic<int> g_stop_requests{0};

namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kVersion = "render-worker 0.1";
constexpr double kRpcTimeout = 10.0;

// Full-frame buffers (3 doubles per pixel) a lease holds at its peak: the renderer's sum, odd
// sum and iteration image, and the sum and odd sum of the previous lease's report, in flight
// while this one renders (BackgroundReport: one at most; its technique layers, if any, are
// charged with the lease). The renderer's sums become the lease's report without a copy.
constexpr uint64_t kWorkerFilmBuffers = 5;

// The budget of a job's scene and film: --max-memory, or less if the machine has less
// available when the scene is loaded.
SceneMemoryBudget scene_memory_budget(uint64_t max_memory) {
    const uint64_t available = available_memory_bytes();
    if (max_memory > 0 && (available == 0 || max_memory <= available))
        return SceneMemoryBudget(max_memory, "worker --max-memory " + format_bytes(max_memory));
    return SceneMemoryBudget(available,
                             "the memory available on the worker's machine, "
                             "MemAvailable in /proc/meminfo");
}

double seconds_since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string host_name() {
    char buf[256] = {};
    if (gethostname(buf, sizeof buf - 1) != 0) return "unknown";
    return buf;
}

// Waits with a growing delay: 0.2 s doubling to 5 s; reset() after a success.
class Backoff {
  public:
    double next() {
        double d = delay_;
        delay_ = std::min(delay_ * 2, 5.0);
        return d;
    }
    void reset() { delay_ = 0.2; }

  private:
    double delay_ = 0.2;
};

bool is_transient(grpc::StatusCode code) {
    return code == grpc::StatusCode::UNAVAILABLE || code == grpc::StatusCode::DEADLINE_EXCEEDED ||
           code == grpc::StatusCode::RESOURCE_EXHAUSTED || code == grpc::StatusCode::ABORTED ||
           code == grpc::StatusCode::CANCELLED;
}

}  // namespace

struct RangeResult {
    std::vector<double> sum, odd_sum;
    std::vector<std::vector<double>> layers;  // the technique layers' sums, in their order
    // An adaptive job's exact sums, one per pixel (empty otherwise).
    std::vector<int64_t> exact_sum, exact_odd;
    uint64_t count = 0, odd_count = 0;
    RenderStats stats;
    double seconds = 0;
    int width = 0, height = 0;
};

Worker::Worker(WorkerOptions options)
    : options_(std::move(options)),
      link_(link_to(0)),
      cache_(options_.cache_dir, options_.cache_max_bytes) {}

std::shared_ptr<Worker::ServerLink> Worker::link_to(size_t index) const {
    auto link = std::make_shared<ServerLink>();
    link->address = options_.servers.at(index);
    link->channel = make_channel(link->address, options_.tls);
    link->stub = v1::WorkerService::NewStub(link->channel);
    return link;
}

void Worker::next_server(const char* why) {
    if (options_.servers.size() < 2) return;
    server_index_ = (server_index_ + 1) % options_.servers.size();
    log_warn("server_switch")
        .kv("from", link_->address)
        .kv("to", options_.servers[server_index_])
        .kv("after", why);
    link_ = link_to(server_index_);
}

void Worker::nap(double seconds) {
    auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < until && g_stop_requests.load() == 0)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
}

bool Worker::register_worker() {
    grpc::ClientContext context;
    prepare_context(context, options_.token, kRpcTimeout);
    v1::RegisterWorkerRequest request;
    request.set_host(host_name());
    request.set_threads(uint32_t(options_.threads > 0
                                     ? options_.threads
                                     : int(std::max(1u, std::thread::hardware_concurrency()))));
    request.set_version(kVersion);
    v1::RegisterWorkerReply reply;
    grpc::Status status = link_->stub->RegisterWorker(&context, request, &reply);
    if (!status.ok()) {
        if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
            status.error_code() == grpc::StatusCode::PERMISSION_DENIED)
            token_rejected_ = true;
        log_warn("register_failed").kv("server", link_->address).kv("status", describe(status));
        return false;
    }
    link_->worker_id = reply.worker_id();
    if (reply.heartbeat_seconds() > 0) heartbeat_seconds_ = reply.heartbeat_seconds();
    log_info("registered")
        .kv("worker", link_->worker_id)
        .kv("server", link_->address)
        .kv("threads", request.threads())
        .kv("heartbeat_s", heartbeat_seconds_);
    return true;
}

int Worker::run() {
    log_info("start").kv("server", link_->address).kv("cache", cache_.dir().string());
    Backoff backoff;
    IdlePoll idle(std::hash<std::string>{}(link_->address + host_name()) ^ uint64_t(getpid()));
    while (g_stop_requests.load() == 0) {
        if (link_->worker_id.empty()) {
            if (!register_worker()) {
                if (token_rejected_) {
                    log_error("token_rejected").kv("hint", "check --token or RENDER_TOKEN");
                    return 1;
                }
                next_server("register");
                nap(backoff.next());
                continue;
            }
            backoff.reset();
        }
        v1::LeaseRequest request;
        request.set_worker_id(link_->worker_id);
        v1::LeaseReply reply;
        grpc::ClientContext context;
        prepare_context(context, options_.token, kRpcTimeout);
        grpc::Status status = link_->stub->Lease(&context, request, &reply);
        if (!status.ok()) {
            log_warn("lease_failed").kv("status", describe(status));
            if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED) {
                log_error("token_rejected").kv("hint", "check --token or RENDER_TOKEN");
                return 1;
            }
            // A server that restarted may not know this worker any more: register again. One
            // that cannot be reached: the next server of the list, if any.
            if (!is_transient(status.error_code()))
                link_->worker_id.clear();
            else
                next_server("lease");
            nap(backoff.next());
            continue;
        }
        backoff.reset();
        if (!reply.granted() || !reply.has_lease()) {
            // Idle with a report on its way: its lease is heartbeaten, or it expires while the
            // server receives or merges the report (nothing else of this worker heartbeats).
            if (!report_in_flight_.wait_for(0) && in_flight_link_ == link_)
                heartbeat(in_flight_lease_, nullptr);
            nap(idle.next());
            continue;
        }
        idle.reset();
        process(reply.lease());
    }
    report_in_flight_.wait();  // a stop delivers the last lease's report first
    log_info("stop").kv("worker", link_->worker_id);
    return 0;
}

grpc::Status Worker::fetch_asset(const std::string& sha256,
                                 const std::function<void(const std::string&)>& sink) {
    grpc::ClientContext context;
    prepare_context(context, options_.token, 300.0);
    v1::FetchAssetRequest request;
    request.set_sha256(sha256);
    std::unique_ptr<grpc::ClientReader<v1::AssetChunk>> reader =
        link_->stub->FetchAsset(&context, request);
    v1::AssetChunk chunk;
    while (reader->Read(&chunk)) sink(chunk.data());
    return reader->Finish();
}

const Scene& Worker::scene_for(const v1::Lease& lease, const std::filesystem::path& scene_file) {
    const v1::RenderSettings& s = lease.settings();
    std::map<std::string, std::string> defines(s.defines().begin(), s.defines().end());
    std::string key =
        lease.job_id() + "\n" + std::to_string(s.width()) + "x" + std::to_string(s.height());
    for (const auto& [name, value] : defines) key += "\n" + name + "=" + value;
    if (scene_ && key == scene_key_) return *scene_;
    scene_.reset();
    scene_key_.clear();
    auto t0 = Clock::now();
    // The job's folder: the scene file's path without the bundle's scene_path.
    std::filesystem::path job_dir = scene_file;
    for (const auto& part : std::filesystem::path(lease.bundle().scene_path())) {
        (void)part;
        job_dir = job_dir.parent_path();
    }
    std::unique_ptr<Scene> scene;
    {
        // Estimated before anything large is allocated: the film's sums, then every buffer the
        // loaders allocate. A scene over the budget fails the job instead of this process.
        SceneMemoryBudget budget = scene_memory_budget(options_.max_memory);
        if (s.width() > 0 && s.height() > 0)
            budget.charge(film_memory_bytes(s.width(), s.height(), kWorkerFilmBuffers),
                          "the film (" + std::to_string(s.width()) + " x " +
                              std::to_string(s.height()) + ")");
        scene = load_scene(scene_file, defines, job_dir);
        scene_memory_ = budget.charged();
    }
    if (s.width() > 0 && s.height() > 0)
        scene->set_camera(scene->camera().with_resolution(int(s.width()), int(s.height())));
    log_info("scene_loaded")
        .kv("job", lease.job_id())
        .kv("scene", scene_file.string())
        .kv("width", scene->camera().width())
        .kv("height", scene->camera().height())
        .kv("seconds", seconds_since(t0));
    scene_ = std::move(scene);
    scene_key_ = key;
    return *scene_;
}

bool Worker::heartbeat(const std::string& lease_id, const v1::WorkerRates* rates) {
    grpc::ClientContext context;
    prepare_context(context, options_.token, kRpcTimeout);
    v1::HeartbeatRequest request;
    request.set_worker_id(link_->worker_id);
    request.add_lease_ids(lease_id);
    if (rates) *request.mutable_rates() = *rates;
    v1::HeartbeatReply reply;
    grpc::Status status = link_->stub->Heartbeat(&context, request, &reply);
    if (!status.ok()) {
        log_warn("heartbeat_failed").kv("lease", lease_id).kv("status", describe(status));
        return true;  // keep rendering: the report decides whether the work still counts
    }
    for (const std::string& id : reply.cancelled_lease_ids())
        if (id == lease_id) return false;
    return true;
}

void Worker::report_failure(const ServerLink& link, const std::string& lease_id,
                            const std::string& error, uint64_t memory_needed, uint64_t memory_limit,
                            bool report_undelivered) {
    grpc::ClientContext context;
    prepare_context(context, options_.token, kRpcTimeout);
    v1::HeartbeatRequest request;
    request.set_worker_id(link.worker_id);
    v1::LeaseFailure* failure = request.add_failed_leases();
    failure->set_lease_id(lease_id);
    failure->set_error(error);
    failure->set_memory_needed(memory_needed);
    failure->set_memory_limit(memory_limit);
    failure->set_report_undelivered(report_undelivered);
    v1::HeartbeatReply reply;
    grpc::Status status = link.stub->Heartbeat(&context, request, &reply);
    if (!status.ok())
        log_warn("failure_report_failed").kv("lease", lease_id).kv("status", describe(status));
}

Worker::Outcome Worker::process(const v1::Lease& lease) {
    const uint64_t first = lease.first_iteration(), end = lease.end_iteration();
    log_info("lease")
        .kv("lease", lease.lease_id())
        .kv("job", lease.job_id())
        .kv("frame", lease.frame())
        .kv("first", first)
        .kv("end", end)
        .kv("algorithm", lease.settings().algorithm());
    auto fail = [&](const std::string& why, uint64_t memory_needed = 0, uint64_t memory_limit = 0) {
        // The server queues the range again and fails the job if it fails on several workers
        // (a refusal for memory excepted: the job waits for a worker with more).
        log_error("lease_failed").kv("lease", lease.lease_id()).kv("error", why);
        report_failure(*link_, lease.lease_id(), why, memory_needed, memory_limit);
        return Outcome::Failed;
    };
    if (first < 1 || end <= first) return fail("empty or invalid iteration range");

    // Assets and scene.
    const Scene* scene = nullptr;
    RenderSettings settings;
    std::string job_folder;  // the job's folder in this worker's cache
    try {
        {
            // Held until the scene is loaded: no worker sharing the cache prunes the folder
            // meanwhile (the loaded scene no longer needs it).
            AssetCache::Use folder =
                cache_.prepare_job(lease.job_id(), lease.bundle(),
                                   [this](const std::string& sha,
                                          const std::function<void(const std::string&)>& sink) {
                                       return fetch_asset(sha, sink);
                                   });
            std::filesystem::path job_dir = folder.scene_file();
            for (const auto& part : std::filesystem::path(lease.bundle().scene_path())) {
                (void)part;
                job_dir = job_dir.parent_path();
            }
            job_folder = job_dir.string();
            scene = &scene_for(lease, folder.scene_file());
        }
        // The same resolution as `render`'s: defaults, the scene's values, the options.
        const v1::RenderSettings& s = lease.settings();
        settings = resolve_render_settings(job_algorithm(s.algorithm(), scene->settings.integrator),
                                           request_options(s), scene->settings);
        settings.threads = options_.threads;
        // The algorithm's own memory (light vertices, merging grids, beams, per-thread
        // buffers), estimated from the settings and charged with the scene's before the first
        // iteration allocates it.
        SceneMemoryBudget budget = scene_memory_budget(options_.max_memory);
        // Against --max-memory the whole job counts. Against the machine's available memory
        // only what this lease allocates: the loaded scene is in use already, and no longer
        // counted as available (charging it again would refuse a job that fits).
        const bool whole_job = options_.max_memory > 0 && budget.limit() == options_.max_memory;
        if (whole_job)
            budget.charge(scene_memory_, "the scene and film");
        else
            budget.charge(film_memory_bytes(uint64_t(scene->camera().width()),
                                            uint64_t(scene->camera().height()), kWorkerFilmBuffers),
                          "the film");
        const IterationMemoryEstimate working =
            estimate_iteration_memory(settings, uint64_t(scene->camera().width()),
                                      uint64_t(scene->camera().height()), options_.threads);
        budget.charge(working.bytes, working.what);
        // The report in flight while this lease renders, of this lease's size: a larger one
        // (another job's frame) is waited for first. Its sum and odd sum are in the film's
        // buffers above; its technique layers are charged here.
        const uint64_t layer_count = TechniqueLayers::names(settings.layers).size();
        if (report_in_flight_.bytes_in_flight() >
            film_memory_bytes(uint64_t(scene->camera().width()), uint64_t(scene->camera().height()),
                              2 + layer_count))
            report_in_flight_.wait();
        if (layer_count > 0)
            budget.charge(
                film_memory_bytes(uint64_t(scene->camera().width()),
                                  uint64_t(scene->camera().height()), layer_count),
                "the " + std::to_string(layer_count) + " technique layers of the report in flight");
        if (settings.adaptive > 0)
            // The renderer's exact sums and counts (32 B per pixel), the report's exact sums
            // (16 B) and the round's mask (1 B).
            budget.charge(
                uint64_t(scene->camera().width()) * uint64_t(scene->camera().height()) * 49,
                "adaptive sampling's exact sums, counts and mask");
    } catch (const std::exception& e) {
        // Files named as in the client's bundle (as the server's submit errors do), not by
        // this worker's cache folder, which the job's owner cannot see.
        const auto* memory = dynamic_cast<const MemoryLimitExceeded*>(&e);
        return fail(
            job_folder.empty() ? std::string(e.what()) : with_bundle_paths(e.what(), job_folder),
            memory ? memory->needed() : 0, memory ? memory->limit() : 0);
    }

    // An adaptive round's mask (docs/reference/adaptive-sampling.md): kept for the round's
    // later leases, fetched once per round. Round 0 renders every pixel.
    const std::vector<uint8_t>* mask = nullptr;
    if (settings.adaptive > 0) {
        const AdaptiveRounds rounds(settings);
        const uint64_t round = lease.adaptive_round();
        if (rounds.round_of(first) != round || rounds.round_of(end - 1) != round)
            return fail("the lease [" + std::to_string(first) + ", " + std::to_string(end) +
                        ") is not within its adaptive round " + std::to_string(round));
        if (round > 0) {
            std::string error;
            mask =
                mask_for(lease, size_t(scene->camera().width()) * scene->camera().height(), &error);
            if (!mask) {
                // The lease is void (its round is over) or the server is away: nothing to
                // render; an undelivered mask is told to the server so the range goes back.
                log_warn("mask_unavailable").kv("lease", lease.lease_id()).kv("error", error);
                report_failure(*link_, lease.lease_id(),
                               "the worker could not get the lease's mask: " + error, 0, 0,
                               /*report_undelivered=*/true);
                return Outcome::Dropped;
            }
        }
    }

    // Render in a thread, one iteration per call (the sum equals one call over the range, and
    // a cancellation takes effect between iterations); heartbeat from this thread.
    // The result's buffers are the renderer's, moved (the memory budget counts them once).
    RangeResult result;
    result.width = scene->camera().width();
    result.height = scene->camera().height();
    const size_t values = size_t(result.width) * size_t(result.height) * 3;
    const size_t layer_count = TechniqueLayers::names(settings.layers).size();
    std::atomic<bool> abandon{false};
    std::mutex mutex;
    std::condition_variable done_cv;
    bool done = false;
    std::string error;
    // Progress of the range so far, for the rates the heartbeats carry.
    std::atomic<uint64_t> done_iterations{0}, done_samples{0}, done_rays{0};
    auto t0 = Clock::now();
    std::thread renderer([&] {
        try {
            // One renderer for the range: its integrator, arena and buffers are made once,
            // and each iteration adds to `sums` (no full-frame allocation or copy per
            // iteration).
            // Tests only: the fault --test-render-fault asked for (worker/render_fault.h).
            if (options_.test_render_fault.kind != RenderFault::Kind::kNone) [[unlikely]]
                options_.test_render_fault.raise(lease.bundle().scene_path());
            IterationRenderer iterations(*scene, settings, lease.frame());
            IterationResult sums = iterations.empty_result();
            const std::span<const uint8_t> active =
                mask ? std::span<const uint8_t>(*mask) : std::span<const uint8_t>();
            for (uint64_t i = first; i < end && !abandon.load(); ++i) {
                iterations.add({i, i + 1}, sums, active);
                done_samples = sums.stats.samples;
                done_rays = sums.stats.rays;
                done_iterations = sums.count;
            }
            // The iteration contract sizes the buffers by the scene's camera; anything else is a
            // broken build or a bug, never to be sent.
            if (sums.sum.values().size() != values || sums.odd_sum.values().size() != values ||
                sums.layers.size() != layer_count)
                throw std::runtime_error("iteration result has " +
                                         std::to_string(sums.sum.values().size()) +
                                         " values, expected " + std::to_string(values));
            result.sum = std::move(sums.sum.values());
            result.odd_sum = std::move(sums.odd_sum.values());
            result.layers.resize(layer_count);
            for (size_t l = 0; l < layer_count; ++l)
                result.layers[l] = std::move(sums.layers.buffer(l).values());
            if (!sums.adaptive.empty()) {
                result.exact_sum = sums.adaptive.exact.sums();
                result.exact_odd = sums.adaptive.exact.odd_sums();
            }
            result.count = sums.count;
            result.odd_count = sums.odd_count;
            result.stats = sums.stats;
        } catch (const std::exception& e) {
            error = e.what();
        } catch (...) {  // whatever escapes the renderer fails the lease, never the process
            error = "the renderer threw an exception that is not a std::exception";
        }
        std::lock_guard<std::mutex> lock(mutex);
        done = true;
        done_cv.notify_all();
    });
    bool cancelled = false;
    {
        std::unique_lock<std::mutex> lock(mutex);
        auto next_beat = Clock::now() + std::chrono::duration<double>(heartbeat_seconds_);
        while (!done) {
            done_cv.wait_for(lock, std::chrono::milliseconds(50));
            if (done) break;
            if (g_stop_requests.load() >= 2 && !abandon) {
                log_warn("abandon").kv("lease", lease.lease_id()).kv("reason", "second signal");
                abandon = true;
            }
            if (Clock::now() >= next_beat && !abandon) {
                lock.unlock();
                const double seconds = seconds_since(t0);
                v1::WorkerRates rates;
                const bool measured = done_iterations.load() > 0 && seconds > 0;
                if (measured) {
                    rates.set_iterations_per_second(double(done_iterations.load()) / seconds);
                    rates.set_samples_per_second(double(done_samples.load()) / seconds);
                    rates.set_rays_per_second(double(done_rays.load()) / seconds);
                }
                bool alive = heartbeat(lease.lease_id(), measured ? &rates : nullptr);
                lock.lock();
                next_beat = Clock::now() + std::chrono::duration<double>(heartbeat_seconds_);
                if (!alive) {
                    cancelled = true;
                    abandon = true;
                }
            }
        }
    }
    renderer.join();
    result.seconds = seconds_since(t0);
    if (!error.empty()) return fail(error);
    if (cancelled) {
        log_info("lease_cancelled").kv("lease", lease.lease_id()).kv("job", lease.job_id());
        return Outcome::Cancelled;
    }
    if (abandon || result.count != end - first) {
        log_warn("lease_abandoned").kv("lease", lease.lease_id());
        return Outcome::Dropped;
    }
    {
        Log line = log_info("rendered");
        line.kv("lease", lease.lease_id())
            .kv("iterations", result.count)
            .kv("seconds", result.seconds)
            .kv("it_per_s", result.seconds > 0 ? double(result.count) / result.seconds : 0.0);
        if (result.stats.vpl_candidates > 0)  // importance-driven VPLs: the acceptance rate
            line.kv("vpl_acceptance",
                    double(result.stats.vpl_accepted) / double(result.stats.vpl_candidates));
        // Rays the guard kept from Embree (core/scene/embree_ray.h): not in the report's
        // header (the protocol has no field for them yet), so logged.
        if (result.stats.invalid_rays > 0) line.kv("invalid_rays", result.stats.invalid_rays);
    }
    // Sent while the next lease renders. The lease stays alive on the server meanwhile (the
    // heartbeats extend all of this worker's leases); a report that cannot be delivered is
    // given up as a foreground one was: its range is leased again once its lease expires
    // (which this worker's heartbeats for later leases postpone, as before).
    const uint64_t bytes = film_memory_bytes(uint64_t(result.width), uint64_t(result.height),
                                             2 + result.layers.size());
    const auto wait_start = Clock::now();
    // One in flight: the render threads idle here only if sending is slower than rendering.
    // This lease is heartbeaten meanwhile: a report slow to deliver (a large one, or one
    // retried while its server is away) must not let it expire, or the range is lost and the
    // loss counts against the job (server/failure_policy.h).
    while (!report_in_flight_.wait_for(heartbeat_seconds_)) {
        if (!heartbeat(lease.lease_id(), nullptr)) {
            log_info("lease_cancelled").kv("lease", lease.lease_id()).kv("job", lease.job_id());
            return Outcome::Cancelled;
        }
    }
    log_info("report_queued")
        .kv("lease", lease.lease_id())
        .kv("bytes", bytes)
        .kv("waited_s", seconds_since(wait_start));
    in_flight_lease_ = lease.lease_id();
    in_flight_link_ = link_;
    report_in_flight_.start(bytes, [this, link = link_, lease, result = std::move(result)] {
        try {
            report(*link, lease, result);
        } catch (const std::exception& e) {  // e.g. bad_alloc building a chunk
            log_error("report_failed").kv("lease", lease.lease_id()).kv("error", e.what());
        }
    });
    return Outcome::Reported;
}

const std::vector<uint8_t>* Worker::mask_for(const v1::Lease& lease, size_t pixels,
                                             std::string* error) {
    const std::string key = lease.job_id() + "\n" + std::to_string(lease.frame()) + "\n" +
                            std::to_string(lease.adaptive_round()) + "\n" +
                            lease.adaptive_mask_sha256();
    if (key == mask_key_ && mask_.size() == pixels) return &mask_;
    mask_key_.clear();
    grpc::ClientContext context;
    prepare_context(context, options_.token, 60.0);
    v1::FetchMaskRequest request;
    request.set_worker_id(link_->worker_id);
    request.set_lease_id(lease.lease_id());
    std::unique_ptr<grpc::ClientReader<v1::MaskChunk>> reader =
        link_->stub->FetchMask(&context, request);
    std::string packed;
    v1::MaskChunk chunk;
    while (reader->Read(&chunk)) {
        if (packed.size() + chunk.data().size() > (pixels + 7) / 8) {
            context.TryCancel();
            break;
        }
        packed += chunk.data();
    }
    if (grpc::Status status = reader->Finish(); !status.ok()) {
        *error = describe(status);
        return nullptr;
    }
    // The mask is the server's of that round: its hash and active count say it arrived whole.
    if (sha256_hex(packed) != lease.adaptive_mask_sha256()) {
        *error = "the mask's SHA-256 differs from the lease's";
        return nullptr;
    }
    try {
        mask_ = unpack_mask(packed, pixels);
    } catch (const std::exception& e) {
        *error = e.what();
        return nullptr;
    }
    uint64_t active = 0;
    for (uint8_t m : mask_) active += m;
    if (active != lease.adaptive_active_pixels()) {
        *error = "the mask has " + std::to_string(active) + " active pixels, the lease says " +
                 std::to_string(lease.adaptive_active_pixels());
        return nullptr;
    }
    mask_key_ = key;
    log_info("mask_fetched")
        .kv("lease", lease.lease_id())
        .kv("round", lease.adaptive_round())
        .kv("active_pixels", active)
        .kv("bytes", packed.size());
    return &mask_;
}

Worker::Outcome Worker::report(const ServerLink& link, const v1::Lease& lease,
                               const RangeResult& result) {
    // Retry while the lease may still be alive (the server may be restarting).
    const double patience = std::max(10.0, lease.expires_in_seconds());
    auto t0 = Clock::now();
    Backoff backoff;
    // The servers to send it to: the one that granted the lease first, then, after a failure
    // to reach it, each other server of the list in turn. Any server of a farm answers a
    // report of a lease another granted: it forwards it to the job's holder, or says at once
    // that nobody will merge it (docs/design/job-store.md, "Reports reaching a non-holder").
    // Retrying only a server that died held this report, and the next lease's behind it,
    // until the patience ran out.
    std::vector<const ServerLink*> targets = {&link};
    std::vector<std::shared_ptr<ServerLink>> others;
    for (size_t i = 0; i < options_.servers.size(); ++i)
        if (options_.servers[i] != link.address) {
            others.push_back(link_to(i));
            targets.push_back(others.back().get());
        }
    size_t attempt = 0;
    for (;;) {
        const ServerLink& to = *targets[attempt++ % targets.size()];
        grpc::ClientContext context;
        prepare_context(context, options_.token, 120.0);
        v1::ReportReply reply;
        std::unique_ptr<grpc::ClientWriter<v1::ReportChunk>> writer =
            to.stub->Report(&context, &reply);
        v1::ReportChunk chunk;
        v1::ReportHeader* header = chunk.mutable_header();
        header->set_lease_id(lease.lease_id());
        header->set_count(result.count);
        header->set_odd_count(result.odd_count);
        header->set_width(uint32_t(result.width));
        header->set_height(uint32_t(result.height));
        header->set_samples(result.stats.samples);
        header->set_rays(result.stats.rays);
        header->set_non_finite(result.stats.non_finite);
        header->set_render_seconds(result.seconds);
        header->set_layer_count(uint32_t(result.layers.size()));
        header->set_vpl_candidates(result.stats.vpl_candidates);
        header->set_vpl_accepted(result.stats.vpl_accepted);
        // One iteration: odd_sum is sum or zero, which the server derives exactly.
        const bool omit_odd = result.count == 1;
        header->set_odd_sum_omitted(omit_odd);
        header->set_exact_sums(!result.exact_sum.empty());
        bool ok = writer->Write(chunk);
        // sum, odd_sum (unless omitted), then the layers, as one little-endian float64
        // sequence cut into <= 1 MiB chunks.
        const size_t per_chunk = kMaxChunkBytes / sizeof(double);
        std::vector<const std::vector<double>*> buffers = {&result.sum};
        if (!omit_odd) buffers.push_back(&result.odd_sum);
        for (const std::vector<double>& layer : result.layers) buffers.push_back(&layer);
        // Then an adaptive job's exact sums, int64 words (the odd one omitted with odd_sum).
        std::vector<std::span<const char>> parts;
        for (const std::vector<double>* buffer : buffers)
            parts.emplace_back(reinterpret_cast<const char*>(buffer->data()),
                               buffer->size() * sizeof(double));
        if (!result.exact_sum.empty()) {
            parts.emplace_back(reinterpret_cast<const char*>(result.exact_sum.data()),
                               result.exact_sum.size() * sizeof(int64_t));
            if (!omit_odd)
                parts.emplace_back(reinterpret_cast<const char*>(result.exact_odd.data()),
                                   result.exact_odd.size() * sizeof(int64_t));
        }
        for (const std::span<const char> part : parts) {
            for (size_t at = 0; ok && at < part.size(); at += per_chunk * sizeof(double)) {
                const size_t n = std::min(per_chunk * sizeof(double), part.size() - at);
                v1::ReportChunk values;
                values.mutable_values()->assign(part.data() + at, n);
                ok = writer->Write(values);
            }
        }
        if (ok) writer->WritesDone();
        grpc::Status status = writer->Finish();
        if (status.ok()) {
            Log line = log_info(reply.merged() ? "reported" : "report_dropped");
            line.kv("lease", lease.lease_id()).kv("merged", reply.merged() ? "true" : "false");
            if (&to != &link) line.kv("through", to.address);
            return reply.merged() ? Outcome::Reported : Outcome::Dropped;
        }
        log_warn("report_failed")
            .kv("lease", lease.lease_id())
            .kv("server", to.address)
            .kv("status", describe(status));
        if (!is_transient(status.error_code()) || seconds_since(t0) > patience ||
            g_stop_requests.load() >= 2) {
            // Said to the server (best effort) so that it re-leases the range now: otherwise
            // the lease lives on while this worker heartbeats its next one, as a heartbeat
            // extends every lease of its worker.
            report_failure(link, lease.lease_id(),
                           "the worker could not deliver its report: " + describe(status), 0, 0,
                           /*report_undelivered=*/true);
            return Outcome::Failed;
        }
        // Plain sleep: a first SIGTERM must not cut short the delivery of finished work. Every
        // server of the list is tried once before the first pause.
        if (attempt % targets.size() == 0)
            std::this_thread::sleep_for(std::chrono::duration<double>(backoff.next()));
    }
}

}  // namespace render::service
