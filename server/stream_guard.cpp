#include "server/stream_guard.h"

#include <algorithm>
#include <cstdio>

#include "core/util/log.h"

namespace render::server {

using Clock = std::chrono::steady_clock;

namespace {

std::string seconds_text(double s) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", s);
    return text;
}

}  // namespace

StreamGuards::StreamGuards(StreamLimits limits) : limits_(limits) {
    watchdog_ = std::thread([this] { watch(); });
}

StreamGuards::~StreamGuards() {
    {
        std::lock_guard lock(mu_);
        stopping_ = true;
    }
    wake_.notify_all();
    watchdog_.join();
}

std::unique_ptr<StreamGuards::Guard> StreamGuards::admit(grpc::ServerContext* context,
                                                         const std::string& what,
                                                         grpc::Status* refused) {
    std::lock_guard lock(mu_);
    if (entries_.size() >= limits_.max_streams) {
        *refused = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                "more than " + std::to_string(limits_.max_streams) +
                                    " asset and result streams are open on this server (server "
                                    "--max-transfer-streams " +
                                    std::to_string(limits_.max_streams) + "): retry later");
        return nullptr;
    }
    entries_.push_back(Entry{context, what, Clock::now()});
    return std::make_unique<Guard>(*this, std::prev(entries_.end()));
}

size_t StreamGuards::open() const {
    std::lock_guard lock(mu_);
    return entries_.size();
}

void StreamGuards::watch() {
    const auto idle = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(limits_.idle_seconds));
    // Checked a few times per idle period: a stream is cancelled at most a quarter late.
    const auto period = std::clamp<Clock::duration>(idle / 4, std::chrono::milliseconds(50),
                                                    std::chrono::seconds(1));
    std::unique_lock lock(mu_);
    while (!stopping_) {
        wake_.wait_for(lock, period);
        const auto now = Clock::now();
        for (Entry& e : entries_)
            if (!e.timed_out && !e.paused && now - e.last_progress > idle) {
                e.timed_out = true;
                // Thread-safe; the handler's blocked Read or Write returns false. The entry
                // (and so the context) lives until the handler's Guard is destroyed, which
                // takes mu_.
                e.context->TryCancel();
                Log("warn", "stream_idle_cancelled")
                    .kv("rpc", e.what)
                    .kv("idle_seconds", limits_.idle_seconds);
            }
    }
}

StreamGuards::Guard::Guard(StreamGuards& owner, std::list<Entry>::iterator entry)
    : owner_(owner), entry_(entry) {}

StreamGuards::Guard::~Guard() {
    std::lock_guard lock(owner_.mu_);
    owner_.entries_.erase(entry_);
}

void StreamGuards::Guard::progress() {
    std::lock_guard lock(owner_.mu_);
    entry_->last_progress = Clock::now();
}

StreamGuards::Guard::Pause::Pause(Guard& guard) : guard_(guard) {
    std::lock_guard lock(guard_.owner_.mu_);
    guard_.entry_->paused = true;
}

StreamGuards::Guard::Pause::~Pause() {
    std::lock_guard lock(guard_.owner_.mu_);
    guard_.entry_->paused = false;
    guard_.entry_->last_progress = Clock::now();
}

bool StreamGuards::Guard::timed_out() const {
    std::lock_guard lock(owner_.mu_);
    return entry_->timed_out;
}

grpc::Status StreamGuards::Guard::idle_status() const {
    std::lock_guard lock(owner_.mu_);
    return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                        entry_->what + " stream cancelled: no data for more than " +
                            seconds_text(owner_.limits_.idle_seconds) +
                            " s (server --stream-idle-timeout)");
}

}  // namespace render::server
