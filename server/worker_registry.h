#pragma once

// The workers the server knows: what each registered with, when it was last heard from, its
// latest rates and its memory limit. In memory only (a restarted server learns them again from
// their next calls). Not thread-safe (the job manager calls it under its lock).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "render.pb.h"
#include "server/failure_policy.h"

namespace render::server {

namespace v1 = ::render::v1;

struct WorkerInfo {
    std::string host;
    uint32_t threads = 0;
    std::string version;
    int64_t last_seen_unix_ms = 0;
    v1::WorkerRates rates;      // from the latest heartbeat with rates or merged report
    uint64_t memory_limit = 0;  // from its latest refusal for memory; 0 = unknown
};

class WorkerRegistry {
  public:
    // A new worker (RegisterWorker); host and version are cut to 256 characters.
    void add(const std::string& id, const v1::RegisterWorkerRequest& request, int64_t now_unix_ms);
    // The worker called now. A worker not registered here (the server restarted since) is
    // added, so that it is listed and counted.
    void touch(const std::string& id, int64_t now_unix_ms);
    void set_rates(const std::string& id, const v1::WorkerRates& rates);
    void set_memory_limit(const std::string& id, uint64_t limit);
    // The worker's memory limit; 0 when unknown.
    uint64_t memory_limit(const std::string& id) const;
    // The workers heard from within `live_ms`, with their memory limits.
    std::vector<WorkerMemory> live(int64_t now_unix_ms, int64_t live_ms) const;
    // Calls fn(id, info) for every worker heard from within `live_ms`, in id order.
    template <class Fn>
    void for_each_live(int64_t now_unix_ms, int64_t live_ms, Fn&& fn) const {
        for (const auto& [id, w] : workers_)
            if (now_unix_ms - w.last_seen_unix_ms <= live_ms) fn(id, w);
    }
    size_t size() const { return workers_.size(); }
    const std::map<std::string, WorkerInfo>& all() const { return workers_; }

  private:
    std::map<std::string, WorkerInfo> workers_;
};

}  // namespace render::server
