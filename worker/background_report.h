#pragma once

// The report of a finished lease, sent by a thread of its own while the worker renders its
// next lease: a report sent in the foreground idled the render threads for its serialisation,
// transfer and the server's merge (docs/results/performance-notes.md, "Reports in the
// background"). One report is in flight at most: start()
// waits for the previous one first, so the worker holds at most one report's buffers besides
// the lease it renders (charged to the memory budget, Worker::process).

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>
#include <utility>

namespace render::service {

class BackgroundReport {
  public:
    BackgroundReport() = default;
    ~BackgroundReport() { wait(); }
    BackgroundReport(const BackgroundReport&) = delete;
    BackgroundReport& operator=(const BackgroundReport&) = delete;

    // Waits for the report in flight, if any, then runs `send` (which owns the report's
    // buffers, `bytes` of them) in a thread until it returns. `send` must not throw.
    template <class Send>
    void start(uint64_t bytes, Send&& send) {
        wait();
        bytes_ = bytes;
        finished_ = false;
        thread_ = std::thread([this, send = std::forward<Send>(send)]() mutable {
            send();
            finished_ = true;
        });
    }
    // Returns once no report is in flight.
    void wait() {
        if (thread_.joinable()) thread_.join();
        bytes_ = 0;
    }
    // Waits up to `seconds` for the report in flight; true when none is in flight any more
    // (then as wait()). The caller heartbeats its finished lease between calls, so that a
    // report slow to deliver does not let the next lease expire (Worker::process).
    bool wait_for(double seconds) {
        const auto until =
            std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
        while (thread_.joinable() && !finished_.load() && std::chrono::steady_clock::now() < until)
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        if (thread_.joinable() && !finished_.load()) return false;
        wait();
        return true;
    }
    // The buffers the report in flight holds (0 when none is, or it has not been waited for
    // since it ended: an upper bound either way).
    uint64_t bytes_in_flight() const { return thread_.joinable() ? bytes_ : 0; }

  private:
    std::thread thread_;
    std::atomic<bool> finished_{false};
    uint64_t bytes_ = 0;
};

}  // namespace render::service
