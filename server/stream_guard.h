#pragma once

// Bounds the bulk-transfer streams (UploadAsset, FetchResult, FetchAsset): each holds one of the
// synchronous server's threads while it is open, so a client that opens one and then neither
// sends nor reads would hold that thread for ever (docs/guide/reliability.md, "Streams and the
// asset store"). A StreamGuards admits at most `max_streams` such streams at once (the next is
// refused with RESOURCE_EXHAUSTED), and a watchdog thread cancels a stream that made no progress
// (no chunk received or sent) for `idle_seconds`: the handler's blocked Read or Write then returns
// false. The workers' Report streams and the clients' WatchJob streams are guarded the same way,
// without a count limit (JobManager::report_streams): a report idle between its chunks, or a
// watcher that stopped reading its events, is cancelled; the time a report waits for its job's
// report slot (the server's doing, not the worker's) does not count (Guard::Pause).

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace render::server {

struct StreamLimits {
    double idle_seconds = 60;  // server --stream-idle-timeout
    size_t max_streams = 64;   // server --max-transfer-streams
};

class StreamGuards {
    struct Entry;

  public:
    explicit StreamGuards(StreamLimits limits);
    ~StreamGuards();
    StreamGuards(const StreamGuards&) = delete;
    StreamGuards& operator=(const StreamGuards&) = delete;

    // One admitted stream; progress() after each chunk, timed_out() once its Read or Write
    // failed, to say why. Unregisters when destroyed (before the handler returns).
    class Guard {
      public:
        Guard(StreamGuards& owner, std::list<Entry>::iterator entry);
        ~Guard();
        Guard(const Guard&) = delete;
        Guard& operator=(const Guard&) = delete;
        void progress();
        bool timed_out() const;
        // The status a handler returns when its stream was cancelled for being idle.
        grpc::Status idle_status() const;

        // While a Pause lives the stream is not idle (the server, not the peer, is waiting);
        // the idle clock restarts when it ends.
        class Pause {
          public:
            explicit Pause(Guard& guard);
            ~Pause();
            Pause(const Pause&) = delete;
            Pause& operator=(const Pause&) = delete;

          private:
            Guard& guard_;
        };

      private:
        StreamGuards& owner_;
        std::list<Entry>::iterator entry_;
    };

    // Admits the stream of `context` ("UploadAsset", ...), or nullptr with *refused set to
    // RESOURCE_EXHAUSTED when max_streams are open.
    std::unique_ptr<Guard> admit(grpc::ServerContext* context, const std::string& what,
                                 grpc::Status* refused);

    size_t open() const;
    const StreamLimits& limits() const { return limits_; }

  private:
    struct Entry {
        grpc::ServerContext* context;
        std::string what;
        std::chrono::steady_clock::time_point last_progress;
        bool timed_out = false;
        bool paused = false;
    };
    void watch();

    const StreamLimits limits_;
    mutable std::mutex mu_;
    std::condition_variable wake_;
    std::list<Entry> entries_;  // guarded by mu_
    bool stopping_ = false;     // guarded by mu_
    std::thread watchdog_;
};

}  // namespace render::server
