#include "server/asset_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <random>
#include <stdexcept>

namespace render::server {

namespace fs = std::filesystem;

AssetStore::AssetStore(fs::path store_dir)
    : assets_dir_(store_dir / "assets"), tmp_dir_(store_dir / "tmp") {
    fs::create_directories(assets_dir_);
    fs::create_directories(tmp_dir_);
}

fs::path AssetStore::path(const std::string& sha256) const {
    return assets_dir_ / sha256;
}

std::optional<uint64_t> AssetStore::size(const std::string& sha256) const {
    if (!is_sha256_hex(sha256)) return std::nullopt;
    std::error_code ec;
    auto status = fs::status(path(sha256), ec);
    if (ec || !fs::is_regular_file(status)) return std::nullopt;
    auto n = fs::file_size(path(sha256), ec);
    if (ec) return std::nullopt;
    return n;
}

AssetStore::Upload::Upload(const AssetStore& store, std::string sha256, uint64_t size)
    : store_(store), sha256_(std::move(sha256)), size_(size) {
    static std::atomic<uint64_t> counter{0};
    std::random_device rd;
    tmp_ = store_.tmp_dir_ /
           ("upload-" + std::to_string(rd()) + "-" + std::to_string(++counter) + ".part");
    fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
}

AssetStore::Upload::~Upload() {
    if (fd_ >= 0) ::close(fd_);
    std::error_code ec;
    fs::remove(tmp_, ec);
}

std::string AssetStore::Upload::write(const std::string& data) {
    if (fd_ < 0) return "cannot create a temporary file in " + store_.tmp_dir_.string();
    if (received_ + data.size() > size_)
        return "asset " + sha256_ + " has more than the declared " + std::to_string(size_) +
               " bytes";
    hash_.update(data);
    const char* p = data.data();
    size_t left = data.size();
    while (left > 0) {
        ssize_t n = ::write(fd_, p, left);
        if (n < 0) return std::string("cannot write asset: ") + std::strerror(errno);
        p += n;
        left -= size_t(n);
    }
    received_ += data.size();
    return {};
}

std::string AssetStore::Upload::commit() {
    if (fd_ < 0) return "cannot create a temporary file in " + store_.tmp_dir_.string();
    if (received_ != size_)
        return "asset " + sha256_ + " has " + std::to_string(received_) + " bytes, declared " +
               std::to_string(size_);
    std::string actual = hash_.hex_digest();
    if (actual != sha256_) return "asset content has sha256 " + actual + ", declared " + sha256_;
    if (::fsync(fd_) != 0) return std::string("cannot sync asset: ") + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    std::error_code ec;
    fs::rename(tmp_, store_.path(sha256_), ec);
    if (ec) return "cannot store asset: " + ec.message();
    return {};
}

void AssetStore::materialize(const std::vector<std::pair<std::string, std::string>>& files,
                             const fs::path& dir) const {
    for (const auto& [relative, sha] : files) {
        fs::path target = dir / relative;
        fs::create_directories(target.parent_path());
        std::error_code ec;
        fs::remove(target, ec);
        fs::create_hard_link(path(sha), target, ec);
        if (ec) {
            ec.clear();
            fs::copy_file(path(sha), target, fs::copy_options::overwrite_existing, ec);
            if (ec)
                throw std::runtime_error("cannot place asset " + relative + ": " + ec.message());
        }
    }
}

}  // namespace render::server
