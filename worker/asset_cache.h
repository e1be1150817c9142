#pragma once

// The worker's on-disk cache: assets by content hash (`DIR/assets/<sha256>`, verified when
// fetched) and job folders (`DIR/jobs/<job_id>/<bundle path>`) that rebuild a scene bundle's
// relative layout, so that the scene's relative file names resolve as on the client. A job
// folder's files are hard links to the assets (copies where the file system has none).
//
// Several workers may share one cache folder. Files are renamed into place, and `DIR/lock`
// (flock) keeps pruning apart from use: preparing a job and loading its scene hold it shared;
// pruning takes it exclusively, and is skipped while anyone holds it.
//
// The cache's size is bounded (`max_bytes`): before a job's missing assets are fetched, the
// least recently used job folders and the assets no job folder links are removed until the
// cache has room for them. The job being prepared is never removed.

#include <cstdint>
#include <filesystem>
#include <functional>
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

    // `max_bytes`: the bound on the bytes the cache's files take (0: none).
    explicit AssetCache(std::filesystem::path dir, uint64_t max_bytes = 0);
    ~AssetCache();
    AssetCache(const AssetCache&) = delete;
    AssetCache& operator=(const AssetCache&) = delete;

    const std::filesystem::path& dir() const { return dir_; }
    uint64_t max_bytes() const { return max_bytes_; }
    std::filesystem::path asset_path(const std::string& sha256) const;

    // A prepared job folder in use: while one is alive, no cache sharing this folder prunes.
    // Keep it until the scene is loaded from the folder.
    class Use {
      public:
        Use(Use&& other) noexcept;
        Use& operator=(Use&& other) noexcept;
        ~Use();
        const std::filesystem::path& scene_file() const { return scene_file_; }

      private:
        friend class AssetCache;
        Use(int lock_fd, std::filesystem::path scene_file);
        int lock_fd_ = -1;
        std::filesystem::path scene_file_;
    };

    // Makes sure every file of the bundle is in the cache (fetching the missing ones, checking
    // their hashes; pruning first to make room for them) and materialized under jobs/<job_id>/.
    // Throws std::runtime_error (bad path, hash mismatch, I/O) or RpcError.
    Use prepare_job(const std::string& job_id, const v1::SceneBundle& bundle, const Fetcher& fetch);

    struct PruneResult {
        bool ran = false;  // false: another user held the cache, nothing was looked at
        uint64_t bytes_before = 0, bytes_after = 0;
        int jobs_removed = 0, assets_removed = 0;
    };
    // Removes, least recently used first, the assets no job folder links and then whole job
    // folders (with the assets only they linked) until the cache's files take at most `budget`
    // bytes or only the folder of job `keep` is left. Leftover temporary files go too.
    PruneResult prune(uint64_t budget, const std::string& keep);

    // The bytes the cache's files take (each file once, however many links it has).
    uint64_t size_bytes() const;

  private:
    void fetch_asset(const std::string& sha256, uint64_t size, const Fetcher& fetch);
    std::string temp_name(const std::string& stem);

    std::filesystem::path dir_;
    uint64_t max_bytes_ = 0;
    int lock_fd_ = -1;  // DIR/lock, open for the prunes (a Use opens its own descriptor)
    uint64_t counter_ = 0;
};

// A gRPC failure while preparing a job (e.g. the server is away or lost the asset).
struct RpcError : std::runtime_error {
    RpcError(const std::string& what, grpc::Status s) : std::runtime_error(what), status(s) {}
    grpc::Status status;
};

}  // namespace render::service
