#pragma once

// Content-addressed assets on disk: STORE/assets/<sha256>. Uploads go to a temporary file,
// are hashed while written and renamed into place only when hash and size match. The store
// has a total size limit (server --max-store-size): an upload reserves its declared size
// before anything is written, and is refused when the stored assets and the uploads in
// progress would exceed the limit.

#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/util/sha256.h"

namespace render::server {

class AssetStore {
  public:
    // `max_bytes`: the limit of the stored assets' total size, 0 for none. The assets already
    // in the store count toward it.
    explicit AssetStore(std::filesystem::path store_dir, uint64_t max_bytes = 0);

    uint64_t max_bytes() const { return max_bytes_; }
    // The stored assets' total size, and the declared sizes of the uploads in progress.
    uint64_t stored_bytes() const;
    uint64_t reserved_bytes() const;

    std::filesystem::path path(const std::string& sha256) const;
    // The asset's size when present.
    std::optional<uint64_t> size(const std::string& sha256) const;
    bool has(const std::string& sha256) const { return size(sha256).has_value(); }

    class Upload {
      public:
        Upload(const AssetStore& store, std::string sha256, uint64_t size);
        ~Upload();
        Upload(const Upload&) = delete;
        Upload& operator=(const Upload&) = delete;
        // Reserves the declared size in the store's limit, before anything is written. Returns
        // an error message when it does not fit (the server answers RESOURCE_EXHAUSTED).
        std::string reserve();
        // Returns an error message when the data exceeds the declared size or cannot be written.
        std::string write(const std::string& data);
        // Checks size and hash and moves the file into place; returns an error message.
        std::string commit();
        uint64_t received() const { return received_; }

      private:
        const AssetStore& store_;
        std::string sha256_;
        uint64_t size_;
        uint64_t received_ = 0;
        Sha256 hash_;
        std::filesystem::path tmp_;
        int fd_ = -1;
        bool reserved_ = false;
    };

    // Deletes an asset (no job references it any more) and takes its size off the store's
    // total; returns the bytes freed (0 when it was not there).
    uint64_t remove(const std::string& sha256);
    // Deletes an asset last touched (stored, or marked by touch()) before `cutoff_unix_ms`;
    // returns the bytes freed (nullopt when it was not there or is newer). Under the lock that
    // an upload's commit takes: an upload of the same asset that lands first keeps it.
    std::optional<uint64_t> remove_if_untouched_since(const std::string& sha256,
                                                      int64_t cutoff_unix_ms);
    // Marks an asset as wanted now (its file's modification time): a client that asked
    // HasAssets is about to submit a job naming it. False when the store does not have it.
    bool touch(const std::string& sha256, int64_t now_unix_ms);
    // The stored assets' sha256 (the files of STORE/assets/).
    std::vector<std::string> list() const;

    // Links (or copies) each (bundle path, sha256) under `dir`. Throws std::runtime_error.
    void materialize(const std::vector<std::pair<std::string, std::string>>& files,
                     const std::filesystem::path& dir) const;

    const std::filesystem::path& tmp_dir() const { return tmp_dir_; }

  private:
    void release(uint64_t bytes) const;

    std::filesystem::path assets_dir_;
    std::filesystem::path tmp_dir_;
    uint64_t max_bytes_;
    mutable std::mutex mu_;
    // Guarded by mu_ (mutable: uploads hold a const store).
    mutable uint64_t stored_ = 0;
    mutable uint64_t reserved_ = 0;
};

}  // namespace render::server
