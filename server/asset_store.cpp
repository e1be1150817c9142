#include "server/asset_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <random>
#include <stdexcept>

#include "core/base/memory_budget.h"
#include "server/write_all.h"

namespace render::server {

namespace fs = std::filesystem;

AssetStore::AssetStore(fs::path store_dir, uint64_t max_bytes)
    : assets_dir_(store_dir / "assets"), tmp_dir_(store_dir / "tmp"), max_bytes_(max_bytes) {
    fs::create_directories(assets_dir_);
    fs::create_directories(tmp_dir_);
    for (const fs::directory_entry& entry : fs::directory_iterator(assets_dir_)) {
        std::error_code ec;
        if (entry.is_regular_file(ec)) {
            const uint64_t n = entry.file_size(ec);
            if (!ec) stored_ += n;
        }
    }
}

uint64_t AssetStore::stored_bytes() const {
    std::lock_guard lock(mu_);
    return stored_;
}

uint64_t AssetStore::reserved_bytes() const {
    std::lock_guard lock(mu_);
    return reserved_;
}

void AssetStore::release(uint64_t bytes) const {
    std::lock_guard lock(mu_);
    reserved_ -= bytes;
}

namespace {

// A file's modification time in Unix milliseconds; nullopt when it cannot be read.
std::optional<int64_t> modified_unix_ms(const fs::path& file) {
    struct stat st {};
    if (::stat(file.c_str(), &st) != 0) return std::nullopt;
    return int64_t(st.st_mtim.tv_sec) * 1000 + int64_t(st.st_mtim.tv_nsec / 1000000);
}

}  // namespace

uint64_t AssetStore::remove(const std::string& sha256) {
    return remove_if_untouched_since(sha256, INT64_MAX).value_or(0);
}

std::optional<uint64_t> AssetStore::remove_if_untouched_since(const std::string& sha256,
                                                              int64_t cutoff_unix_ms) {
    // The check and the removal under mu_, as commit() renames under it: a re-upload of this
    // asset that lands first has a new time and is kept; one that lands after stores it anew.
    std::lock_guard lock(mu_);
    const std::optional<uint64_t> n = size(sha256);
    if (!n) return std::nullopt;
    if (cutoff_unix_ms != INT64_MAX) {
        const std::optional<int64_t> touched = modified_unix_ms(path(sha256));
        if (!touched || *touched >= cutoff_unix_ms) return std::nullopt;
    }
    std::error_code ec;
    if (!fs::remove(path(sha256), ec) || ec) return std::nullopt;
    stored_ -= std::min(stored_, *n);
    return *n;
}

bool AssetStore::touch(const std::string& sha256, int64_t now_unix_ms) {
    std::lock_guard lock(mu_);
    if (!has(sha256)) return false;
    struct timespec times[2];
    times[0].tv_sec = now_unix_ms / 1000;
    times[0].tv_nsec = long(now_unix_ms % 1000) * 1000000;
    times[1] = times[0];
    // A file that cannot be touched keeps its older time: it may then be collected before the
    // submit, which fails with a clear error (the client uploads it again).
    ::utimensat(AT_FDCWD, path(sha256).c_str(), times, 0);
    return true;
}

std::vector<std::string> AssetStore::list() const {
    std::vector<std::string> out;
    std::error_code ec;
    for (fs::directory_iterator it(assets_dir_, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (is_sha256_hex(name)) out.push_back(name);
    }
    return out;
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
    if (reserved_) store_.release(size_);
    if (fd_ >= 0) ::close(fd_);
    std::error_code ec;
    fs::remove(tmp_, ec);
}

std::string AssetStore::Upload::reserve() {
    if (reserved_) return {};
    std::lock_guard lock(store_.mu_);
    // An asset the store holds already only replaces itself: the store does not grow.
    if (store_.has(sha256_)) return {};
    const uint64_t used = store_.stored_ + store_.reserved_;
    if (store_.max_bytes_ > 0 && (size_ > store_.max_bytes_ || used > store_.max_bytes_ - size_))
        return "the asset store is full: an asset of " + format_bytes(size_) + " (" +
               std::to_string(size_) + " bytes) does not fit beside the " +
               format_bytes(store_.stored_) + " stored and " + format_bytes(store_.reserved_) +
               " being uploaded, within the store's limit of " + format_bytes(store_.max_bytes_) +
               " (server --max-store-size)";
    store_.reserved_ += size_;
    reserved_ = true;
    return {};
}

std::string AssetStore::Upload::write(const std::string& data) {
    if (fd_ < 0) return "cannot create a temporary file in " + store_.tmp_dir_.string();
    if (received_ + data.size() > size_)
        return "asset " + sha256_ + " has more than the declared " + std::to_string(size_) +
               " bytes";
    hash_.update(data);
    if (!write_all(fd_, data.data(), data.size()))
        return std::string("cannot write asset: ") + std::strerror(errno);
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
    // Under the store's lock, so that two uploads of the same new asset count it once.
    std::lock_guard lock(store_.mu_);
    const bool replaces = store_.has(sha256_);
    std::error_code ec;
    fs::rename(tmp_, store_.path(sha256_), ec);
    if (ec) return "cannot store asset: " + ec.message();
    if (!replaces) store_.stored_ += size_;
    if (reserved_) {
        store_.reserved_ -= size_;
        reserved_ = false;
    }
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
