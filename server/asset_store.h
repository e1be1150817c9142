#pragma once

// Content-addressed assets on disk: STORE/assets/<sha256>. Uploads go to a temporary file,
// are hashed while written and renamed into place only when hash and size match.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/util/sha256.h"

namespace render::server {

class AssetStore {
  public:
    explicit AssetStore(std::filesystem::path store_dir);

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
    };

    // Links (or copies) each (bundle path, sha256) under `dir`. Throws std::runtime_error.
    void materialize(const std::vector<std::pair<std::string, std::string>>& files,
                     const std::filesystem::path& dir) const;

    const std::filesystem::path& tmp_dir() const { return tmp_dir_; }

  private:
    std::filesystem::path assets_dir_;
    std::filesystem::path tmp_dir_;
};

}  // namespace render::server
