// `client watch` (and `submit --wait`): follows the job's events until it ends, riding out a
// short server restart (or moving to the next server of --server's list), polling when the
// server has no room for another watcher.

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "client/commands.h"
#include "client/progress.h"

namespace render::service {

int watch(const Connection& c, const std::string& job_id) {
    ProgressDisplay display(isatty(STDERR_FILENO));
    v1::Job last;
    bool have = false;
    int unavailable = 0;
    for (;;) {
        grpc::ClientContext context;
        c.prepare(context, 0);  // a watch lasts as long as the job
        v1::WatchJobRequest request;
        request.set_job_id(job_id);
        std::unique_ptr<grpc::ClientReader<v1::JobEvent>> reader =
            c.stub->WatchJob(&context, request);
        v1::JobEvent event;
        while (reader->Read(&event)) {
            last = event.job();
            have = true;
            unavailable = 0;
            display.update(last);
            if (is_terminal(last.state())) break;
        }
        if (have && is_terminal(last.state())) {
            context.TryCancel();
            reader->Finish();
            break;
        }
        grpc::Status status = reader->Finish();
        if (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
            // The server has as many watchers as it serves: poll instead.
            last = get_job(c, job_id);
            have = true;
            display.update(last);
            if (is_terminal(last.state())) break;
            std::this_thread::sleep_for(std::chrono::seconds(1));
            continue;
        }
        if (!status.ok()) {
            // Ride out a short server restart, or move to the next server of the list;
            // give up after ~30 s.
            if (status.error_code() == grpc::StatusCode::UNAVAILABLE && ++unavailable <= 12) {
                if (!c.fail_over())
                    std::this_thread::sleep_for(std::chrono::milliseconds(250 * unavailable));
                continue;
            }
            throw RpcFailure("WatchJob", status);
        }
        // The stream ended without a final state: ask, and watch again if needed.
        last = get_job(c, job_id);
        have = true;
        display.update(last);
        if (is_terminal(last.state())) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    display.finish();
    uint64_t iterations = 0;
    double seconds = 0, error = 0;
    for (const auto& f : last.frames()) {
        iterations += f.iterations_done();
        seconds = std::max(seconds, f.render_seconds());
        error = std::max(error, f.relative_error());
    }
    std::fprintf(stderr, "job %s %s: %d frame(s), %llu iterations, %s, estimated error %.3g%s%s\n",
                 last.id().c_str(), state_name(last.state()), last.frames_size(),
                 (unsigned long long)iterations, render::format_seconds(seconds).c_str(), error,
                 last.error().empty() ? "" : ": ", last.error().c_str());
    return last.state() == v1::JOB_STATE_DONE ? 0 : 1;
}

}  // namespace render::service
