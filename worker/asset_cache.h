#pragma once

// The worker's on-disk cache: assets by content hash (`DIR/assets/<sha256>`, verified when
// fetched) and job folders (`DIR/jobs/<job_id>/<bundle path>`) that rebuild a scene bundle's
// relative layout, so that the scene's relative file names resolve as on the client.

#include <filesystem>
#include <functional>
#include <mutex>
#include <set>
#include <string>

#include "render.grpc.pb.h"

namespace render::service {

// Throws std::runtime_error unless `path` is a clean relative bundle path (forward slashes,
// no "..", ".", empty or absolute parts).
void check_bundle_path(const std::string& path);

class AssetCache {
  public:
    // Fetches an asset's chunks into the given callback sink; returns an error status or OK.
    using Fetcher = std::function<grpc::Status(const std::string& sha256,
                                               const std::function<void(const std::string&)>&)>;

    explicit AssetCache(std::filesystem::path dir);

    const std::filesystem::path& dir() const { return dir_; }
    std::filesystem::path asset_path(const std::string& sha256) const;

    // Makes sure every file of the bundle is in the cache (fetching the missing ones, checking
    // their hashes) and materialized under jobs/<job_id>/. Returns the scene file's path.
    // Throws std::runtime_error (bad path, hash mismatch, I/O) or RpcError.
    std::filesystem::path prepare_job(const std::string& job_id, const v1::SceneBundle& bundle,
                                      const Fetcher& fetch);

  private:
    void fetch_asset(const std::string& sha256, uint64_t size, const Fetcher& fetch);
    std::string temp_name(const std::string& stem);

    std::filesystem::path dir_;
    std::set<std::string> prepared_jobs_;
    uint64_t counter_ = 0;
};

// A gRPC failure while preparing a job (e.g. the server is away or lost the asset).
struct RpcError : std::runtime_error {
    RpcError(const std::string& what, grpc::Status s) : std::runtime_error(what), status(s) {}
    grpc::Status status;
};

}  // namespace render::service
