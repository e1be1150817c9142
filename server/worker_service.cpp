#include "server/worker_service.h"

#include <chrono>
#include <memory>
#include <optional>
#include <thread>

#include "core/image/fixed_point_sums.h"
#include "core/util/log.h"
#include "core/util/sha256.h"
#include "server/job_service.h"
#include "server/report_values.h"
#include "service/rpc.h"

namespace render::server {

using grpc::Status;
using grpc::StatusCode;

Status WorkerServiceImpl::RegisterWorker(grpc::ServerContext* context,
                                         const v1::RegisterWorkerRequest* request,
                                         v1::RegisterWorkerReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    manager_.register_worker(*request, reply);
    return Status::OK;
}

Status WorkerServiceImpl::Lease(grpc::ServerContext* context, const v1::LeaseRequest* request,
                                v1::LeaseReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    return manager_.lease(*request, reply);
}

Status WorkerServiceImpl::FetchAsset(grpc::ServerContext* context,
                                     const v1::FetchAssetRequest* request,
                                     grpc::ServerWriter<v1::AssetChunk>* writer) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    if (!is_sha256_hex(request->sha256()))
        return Status(StatusCode::INVALID_ARGUMENT, "sha256 must be 64 lower-case hex digits");
    if (!manager_.assets().has(request->sha256()))
        return Status(StatusCode::NOT_FOUND, "asset " + request->sha256() + " not found");
    Status refused;
    auto guard = manager_.worker_streams().admit(context, "FetchAsset", &refused);
    if (!guard) return refused;
    bool first = true;
    Status s = stream_file(manager_.assets().path(request->sha256()),
                           [&](std::string&& data, uint64_t total) {
                               v1::AssetChunk chunk;
                               if (first) {
                                   chunk.set_sha256(request->sha256());
                                   chunk.set_size(total);
                                   first = false;
                               }
                               chunk.set_data(std::move(data));
                               if (!writer->Write(chunk)) return false;
                               guard->progress();
                               return true;
                           });
    if (!s.ok() && guard->timed_out()) s = guard->idle_status();
    return s;
}

Status WorkerServiceImpl::FetchMask(grpc::ServerContext* context,
                                    const v1::FetchMaskRequest* request,
                                    grpc::ServerWriter<v1::MaskChunk>* writer) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    std::string packed;
    if (Status s = manager_.fetch_mask(*request, &packed); !s.ok()) return s;
    // At most 8 MiB (an 8192 x 8192 film): in chunks of at most 1 MiB, as every bulk stream.
    for (size_t at = 0; at < packed.size() || at == 0; at += service::kMaxChunkBytes) {
        v1::MaskChunk chunk;
        chunk.set_data(packed.substr(at, service::kMaxChunkBytes));
        chunk.set_total_size(packed.size());
        if (!writer->Write(chunk)) return Status(StatusCode::CANCELLED, "FetchMask cancelled");
        if (packed.empty()) break;
    }
    return Status::OK;
}

Status WorkerServiceImpl::Heartbeat(grpc::ServerContext* context,
                                    const v1::HeartbeatRequest* request,
                                    v1::HeartbeatReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    return manager_.heartbeat(*request, reply);
}

Status WorkerServiceImpl::forward_report(const std::string& holder, size_t max_value_bytes,
                                         v1::ReportChunk&& header_chunk,
                                         grpc::ServerReader<v1::ReportChunk>* reader,
                                         std::unique_ptr<StreamGuards::Guard>& guard,
                                         v1::ReportReply* reply) {
    const std::string lease_id = header_chunk.header().lease_id();
    // Received whole before it is sent on (the holder's stream rules apply to this server's
    // sending, not to the worker's): at most the job's largest report.
    std::vector<v1::ReportChunk> chunks;
    chunks.push_back(std::move(header_chunk));
    size_t bytes = 0;
    v1::ReportChunk chunk;
    while (reader->Read(&chunk)) {
        guard->progress();
        bytes += chunk.values().size();
        if (chunk.has_header() || bytes > max_value_bytes)
            return Status(StatusCode::INVALID_ARGUMENT, chunk.has_header()
                                                            ? "a report has exactly one header"
                                                            : "report larger than its job's sums");
        chunks.push_back(std::move(chunk));
    }
    if (guard->timed_out()) return guard->idle_status();
    // Received: sending it on may take longer than the idle timeout and must not be cut.
    guard.reset();
    manager_.metrics().report_received(chunks.front().header().ByteSizeLong() + bytes);
    const Status s = forwarder_->forward(holder, chunks, reply);
    const char* result = !s.ok() ? "failed" : reply->merged() ? "merged" : "not_merged";
    manager_.metrics().report_forwarded(result);
    Log log(s.ok() ? "info" : "warn", "report_forwarded");
    log.kv("lease", lease_id).kv("holder", holder).kv("bytes", bytes).kv("result", result);
    if (!s.ok()) {
        log.kv("error", s.error_message());
        // Not reached: answered as an unknown lease is (the holder leases the range again when
        // the lease expires), so the worker does not retry against this server for ever.
        reply->Clear();
        reply->set_merged(false);
    }
    return Status::OK;
}

Status WorkerServiceImpl::Report(grpc::ServerContext* context,
                                 grpc::ServerReader<v1::ReportChunk>* reader,
                                 v1::ReportReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    // A worker that stalls mid-report (or opens the stream and sends nothing) would hold this
    // thread, and its lease, for ever: the stream is cancelled after --stream-idle-timeout
    // seconds without a chunk, and its lease's range is queued again at once.
    Status refused;
    std::unique_ptr<StreamGuards::Guard> guard =
        manager_.long_streams().admit(context, "Report", &refused);
    if (!guard) return refused;
    v1::ReportChunk chunk;
    if (!reader->Read(&chunk) || !chunk.has_header()) {
        if (guard->timed_out()) return guard->idle_status();
        return Status(StatusCode::INVALID_ARGUMENT, "a report must start with its header");
    }
    guard->progress();
    const v1::ReportHeader header = chunk.header();
    size_t n = 0, layers = 0, exact_words = 0;
    bool drop = false;
    if (Status s = manager_.check_report(header, &n, &layers, &exact_words, &drop); !s.ok()) {
        Log("warn", "report_rejected")
            .kv("lease", header.lease_id())
            .kv("error", s.error_message());
        return s;
    }
    if (drop && forwarder_ && !ReportForwarder::forwarded(*context)) {
        size_t max_value_bytes = 0;
        const std::string holder = manager_.report_holder(header.lease_id(), &max_value_bytes);
        if (!holder.empty())
            return forward_report(holder, max_value_bytes, std::move(chunk), reader, guard, reply);
    }
    if (drop) {
        uint64_t bytes = header.ByteSizeLong();
        while (reader->Read(&chunk)) {
            guard->progress();
            bytes += chunk.values().size();
        }
        if (guard->timed_out()) return guard->idle_status();
        manager_.metrics().report_received(bytes);
        manager_.metrics().report_dropped("unknown_lease");
        Log("warn", "report_dropped").kv("lease", header.lease_id()).kv("reason", "unknown_lease");
        reply->set_merged(false);
        return Status::OK;
    }
    // One report of a job at a time holds its values (JobManager::report_slot): the wait is
    // logged. A lease unknown by now is read and dropped by report() as before.
    const auto wait_start = std::chrono::steady_clock::now();
    std::shared_ptr<void> slot;
    {
        // Waiting for another report of the job is not the worker being idle.
        StreamGuards::Guard::Pause paused(*guard);
        slot = manager_.report_slot(header.lease_id());
    }
    const auto receiving = std::chrono::steady_clock::now();
    const auto waited = receiving - wait_start;
    // sum, odd_sum (unless omitted), then the layers' sums: one float64 sequence, merged only
    // once it is complete (a report that fails half-way changes nothing). A large report is
    // spooled to a file while it arrives (server/report_values.h, --spool-reports-above), so
    // that the frame's sums and a whole report are not in memory at once. Each value is
    // checked to be finite as soon as its last byte arrives, not in a pass of its own.
    const size_t sums = header.odd_sum_omitted() ? 1 : 2;
    // An adaptive job's exact sums follow as int64 words, each at most the largest quantized
    // value times the range's iterations (core/image/fixed_point_sums.h).
    const size_t count = n * (sums + layers) + exact_words;
    const ReportValues::Words words{
        exact_words > 0 ? n * (sums + layers) : SIZE_MAX,
        FixedPointSums::kMaxQuantized * int64_t(std::min<uint64_t>(header.count(), 1u << 22))};
    const size_t expected = count * sizeof(double);
    std::optional<ReportValues> values;
    if (expected >= manager_.options().spool_reports_above) {
        try {
            values.emplace(ReportValues::spooled(manager_.report_spool_folder(), count, words));
        } catch (const std::exception& e) {
            // Received in memory, as a smaller report would be: the server's memory, not the
            // report, pays for a spool folder it cannot write.
            Log("warn", "report_spool_failed").kv("lease", header.lease_id()).kv("error", e.what());
        }
    }
    if (!values) values.emplace(ReportValues::in_memory(count, words));
    while (reader->Read(&chunk)) {
        guard->progress();
        if (chunk.has_header())
            return Status(StatusCode::INVALID_ARGUMENT, "a report has exactly one header");
        bool spool_failed = false;
        if (std::string error = values->append(chunk.values(), &spool_failed); !error.empty()) {
            if (spool_failed) Log("error", "report_spool_failed").kv("error", error);
            // A full spool disk is the server's trouble: the worker sends the report again.
            return Status(spool_failed ? StatusCode::UNAVAILABLE : StatusCode::INVALID_ARGUMENT,
                          error);
        }
    }
    if (guard->timed_out()) {
        manager_.report_stream_idle(header.lease_id());
        return guard->idle_status();
    }
    // Received: the merge below may take longer than the idle timeout and must not be cut.
    guard.reset();
    if (const double delay = manager_.options().report_delay_seconds; delay > 0) {
        Log("info", "report_delayed").kv("lease", header.lease_id()).kv("seconds", delay);
        const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(delay);
        while (std::chrono::steady_clock::now() < until && !context->IsCancelled())
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (context->IsCancelled()) {
        Log("warn", "report_cancelled").kv("lease", header.lease_id());
        return Status(StatusCode::CANCELLED, "report cancelled");
    }
    const size_t received = values->received_bytes();
    if (received != expected)
        return Status(
            StatusCode::INVALID_ARGUMENT,
            "report has " + std::to_string(received) + " bytes of values, expected " +
                std::to_string(expected) + " (sum, " +
                (sums == 2 ? "odd_sum and " : "no odd_sum, ") + std::to_string(layers) +
                " layers, " + std::to_string(n) + " float64 each" +
                (exact_words > 0 ? ", then " + std::to_string(exact_words) + " int64 exact sums"
                                 : std::string()) +
                ")");
    const auto received_at = std::chrono::steady_clock::now();
    manager_.metrics().report_received(header.ByteSizeLong() + received);
    bool merged = false;
    const bool spooled = values->is_spooled();
    if (Status s = manager_.report(header, std::move(*values), &merged); !s.ok()) return s;
    reply->set_merged(merged);
    // Cost of a report for the performance report (docs/results/performance.md): bytes on the wire
    // (header + values), time spent receiving the chunks and time spent merging (accumulate +
    // checkpoint + store).
    using us = std::chrono::microseconds;
    Log("info", "report_received")
        .kv("lease", header.lease_id())
        .kv("bytes", header.ByteSizeLong() + received)
        .kv("iterations", header.count())
        .kv("wait_us", std::chrono::duration_cast<us>(waited).count())
        .kv("receive_us", std::chrono::duration_cast<us>(received_at - receiving).count())
        .kv("merge_us",
            std::chrono::duration_cast<us>(std::chrono::steady_clock::now() - received_at).count())
        .kv("merged", merged ? 1 : 0)
        .kv("spooled", spooled ? 1 : 0);
    return Status::OK;
}

}  // namespace render::server
