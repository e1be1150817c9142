#include "server/worker_registry.h"

namespace render::server {

void WorkerRegistry::add(const std::string& id, const v1::RegisterWorkerRequest& request,
                         int64_t now_unix_ms) {
    WorkerInfo& w = workers_[id];
    w.host = request.host().substr(0, 256);
    w.threads = request.threads();
    w.version = request.version().substr(0, 256);
    w.last_seen_unix_ms = now_unix_ms;
}

void WorkerRegistry::touch(const std::string& id, int64_t now_unix_ms) {
    workers_[id].last_seen_unix_ms = now_unix_ms;
}

void WorkerRegistry::set_rates(const std::string& id, const v1::WorkerRates& rates) {
    workers_[id].rates = rates;
}

void WorkerRegistry::set_memory_limit(const std::string& id, uint64_t limit) {
    workers_[id].memory_limit = limit;
}

uint64_t WorkerRegistry::memory_limit(const std::string& id) const {
    auto it = workers_.find(id);
    return it == workers_.end() ? 0 : it->second.memory_limit;
}

std::vector<WorkerMemory> WorkerRegistry::live(int64_t now_unix_ms, int64_t live_ms) const {
    std::vector<WorkerMemory> out;
    for_each_live(now_unix_ms, live_ms, [&](const std::string& id, const WorkerInfo& w) {
        out.push_back({id, w.memory_limit});
    });
    return out;
}

}  // namespace render::server
