#include "worker/asset_cache.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <utility>
#include <vector>

#include "core/util/log.h"
#include "core/util/sha256.h"

namespace render::service {

namespace fs = std::filesystem;

void check_bundle_path(const std::string& path) {
    auto bad = [&](const char* why) {
        throw std::runtime_error("bad bundle path \"" + path + "\": " + why);
    };
    if (path.empty()) bad("empty");
    if (path[0] == '/') bad("absolute");
    if (path.find('\\') != std::string::npos) bad("backslash");
    if (path.find('\0') != std::string::npos) bad("NUL byte");
    size_t start = 0;
    while (start <= path.size()) {
        size_t end = path.find('/', start);
        if (end == std::string::npos) end = path.size();
        std::string part = path.substr(start, end - start);
        if (part.empty() || part == "." || part == "..") bad("empty, '.' or '..' component");
        start = end + 1;
    }
}

namespace {

// Opens DIR/lock (created if missing). Throws std::runtime_error.
int open_lock_file(const fs::path& dir) {
    const fs::path path = dir / "lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
        throw std::runtime_error("cannot open " + path.string() + ": " + std::strerror(errno));
    return fd;
}

int flock_retrying(int fd, int operation) {
    int rc;
    do rc = ::flock(fd, operation);
    while (rc != 0 && errno == EINTR);
    return rc;
}

int64_t mtime_ns(const struct stat& st) {
    return int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
}

void touch(const fs::path& path) {
    std::error_code ec;  // a time stamp is a hint for pruning, never worth failing a job
    fs::last_write_time(path, fs::file_time_type::clock::now(), ec);
}

// What the cache holds: every file once (by inode), the assets, the job folders.
struct CacheContents {
    using Key = std::pair<dev_t, ino_t>;
    struct Inode {
        uint64_t size = 0;
        uint64_t links = 0;  // left on disk (st_nlink, minus the links removed since)
    };
    struct Asset {
        fs::path path;
        Key key;
        int64_t used_ns = 0;  // last linked into a job folder, or fetched
    };
    struct Job {
        std::string id;
        fs::path dir;
        int64_t used_ns = 0;  // last prepared
        std::vector<std::pair<fs::path, Key>> files;
    };
    std::map<Key, Inode> inodes;
    std::vector<Asset> assets;
    std::vector<Job> jobs;
    std::vector<std::pair<fs::path, Key>> temporary;  // tmp/: files being fetched, or left over
    uint64_t bytes = 0;

    // Counts a regular file; returns its key, or nothing if it is not one (or vanished).
    std::optional<Key> add(const fs::path& path, struct stat* out = nullptr) {
        struct stat st {};
        if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
        const Key key{st.st_dev, st.st_ino};
        auto [it, inserted] = inodes.try_emplace(key);
        if (inserted) {
            it->second = {uint64_t(st.st_size), uint64_t(st.st_nlink)};
            bytes += uint64_t(st.st_size);
        }
        if (out) *out = st;
        return key;
    }

    // Removes one link; the file's bytes are free once its last link is gone.
    bool remove_link(const fs::path& path, const Key& key) {
        std::error_code ec;
        if (!fs::remove(path, ec) || ec) return false;
        Inode& inode = inodes[key];
        if (inode.links > 0 && --inode.links == 0) bytes -= inode.size;
        return true;
    }

    static CacheContents scan(const fs::path& dir) {
        CacheContents c;
        std::error_code ec;
        for (fs::directory_iterator it(dir / "assets", ec), end; !ec && it != end;
             it.increment(ec)) {
            struct stat st {};
            if (auto key = c.add(it->path(), &st))
                c.assets.push_back({it->path(), *key, mtime_ns(st)});
        }
        ec.clear();
        for (fs::directory_iterator it(dir / "jobs", ec), end; !ec && it != end; it.increment(ec)) {
            struct stat st {};
            if (::lstat(it->path().c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) continue;
            Job job{it->path().filename().string(), it->path(), mtime_ns(st), {}};
            std::error_code walk;
            for (fs::recursive_directory_iterator f(it->path(), walk), fend; !walk && f != fend;
                 f.increment(walk))
                if (auto key = c.add(f->path())) job.files.emplace_back(f->path(), *key);
            c.jobs.push_back(std::move(job));
        }
        ec.clear();
        for (fs::directory_iterator it(dir / "tmp", ec), end; !ec && it != end; it.increment(ec))
            if (auto key = c.add(it->path())) c.temporary.emplace_back(it->path(), *key);
        return c;
    }
};

}  // namespace

AssetCache::AssetCache(fs::path dir, uint64_t max_bytes)
    : dir_(std::move(dir)), max_bytes_(max_bytes) {
    fs::create_directories(dir_ / "assets");
    fs::create_directories(dir_ / "jobs");
    fs::create_directories(dir_ / "tmp");
    lock_fd_ = open_lock_file(dir_);
}

AssetCache::~AssetCache() {
    if (lock_fd_ >= 0) ::close(lock_fd_);
}

AssetCache::Use::Use(int lock_fd, fs::path scene_file)
    : lock_fd_(lock_fd), scene_file_(std::move(scene_file)) {}

AssetCache::Use::Use(Use&& other) noexcept
    : lock_fd_(std::exchange(other.lock_fd_, -1)), scene_file_(std::move(other.scene_file_)) {}

AssetCache::Use& AssetCache::Use::operator=(Use&& other) noexcept {
    if (this != &other) {
        if (lock_fd_ >= 0) ::close(lock_fd_);
        lock_fd_ = std::exchange(other.lock_fd_, -1);
        scene_file_ = std::move(other.scene_file_);
    }
    return *this;
}

AssetCache::Use::~Use() {
    if (lock_fd_ >= 0) ::close(lock_fd_);  // closing the descriptor releases its flock
}

fs::path AssetCache::asset_path(const std::string& sha256) const {
    return dir_ / "assets" / sha256;
}

std::string AssetCache::temp_name(const std::string& stem) {
    return stem + "." + std::to_string(getpid()) + "." + std::to_string(++counter_) + ".tmp";
}

void AssetCache::fetch_asset(const std::string& sha256, uint64_t size, const Fetcher& fetch) {
    fs::path tmp = dir_ / "tmp" / temp_name(sha256);
    Sha256 hash;
    uint64_t written = 0;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw std::runtime_error("cannot write " + tmp.string());
        grpc::Status status = fetch(sha256, [&](const std::string& data) {
            out.write(data.data(), std::streamsize(data.size()));
            hash.update(data.data(), data.size());
            written += data.size();
        });
        out.close();
        if (!status.ok()) {
            fs::remove(tmp);
            throw RpcError("FetchAsset " + sha256 + " failed", status);
        }
        if (!out) {
            fs::remove(tmp);
            throw std::runtime_error("error writing " + tmp.string());
        }
    }
    std::string got = hash.hex_digest();
    if (got != sha256 || (size != 0 && written != size)) {
        fs::remove(tmp);
        throw std::runtime_error("asset " + sha256 + " arrived corrupted (sha256 " + got + ", " +
                                 std::to_string(written) + " bytes)");
    }
    fs::rename(tmp, asset_path(sha256));  // atomic: other workers sharing the cache are safe
    log_info("asset_fetched").kv("sha256", sha256).kv("bytes", written);
}

AssetCache::Use AssetCache::prepare_job(const std::string& job_id, const v1::SceneBundle& bundle,
                                        const Fetcher& fetch) {
    check_bundle_path(job_id);
    if (job_id.find('/') != std::string::npos) throw std::runtime_error("bad job id " + job_id);
    check_bundle_path(bundle.scene_path());
    fs::path job_dir = dir_ / "jobs" / job_id;
    bool scene_listed = false;
    for (const v1::BundleFile& file : bundle.files()) {
        check_bundle_path(file.path());
        if (!is_sha256_hex(file.sha256()))
            throw std::runtime_error("bad sha256 \"" + file.sha256() + "\" for " + file.path());
        scene_listed |= file.path() == bundle.scene_path();
    }
    if (!scene_listed)
        throw std::runtime_error("scene " + bundle.scene_path() + " is not among the files");

    // Room for what must be fetched, made before it arrives: a bounded cache (an emptyDir
    // with a size limit, say) never holds more than its bound plus the job in use.
    std::error_code ec;
    bool complete = true;
    uint64_t to_fetch = 0;
    for (const v1::BundleFile& file : bundle.files()) {
        if (fs::exists(job_dir / file.path(), ec)) continue;
        complete = false;
        if (!fs::exists(asset_path(file.sha256()), ec)) to_fetch += file.size();
    }
    if (!complete && max_bytes_ > 0) {
        const uint64_t budget = max_bytes_ > to_fetch ? max_bytes_ - to_fetch : 0;
        const PruneResult pruned = prune(budget, job_id);
        if (pruned.ran && pruned.bytes_after + to_fetch > max_bytes_)
            log_warn("cache_over_limit")
                .kv("job", job_id)
                .kv("cache_bytes", pruned.bytes_after)
                .kv("to_fetch_bytes", to_fetch)
                .kv("limit_bytes", max_bytes_);
    }

    Use use(open_lock_file(dir_), job_dir / bundle.scene_path());
    if (flock_retrying(use.lock_fd_, LOCK_SH) != 0)
        throw std::runtime_error("cannot lock " + (dir_ / "lock").string() + ": " +
                                 std::strerror(errno));
    // Checked again under the lock: another worker's prune may have run in between.
    for (const v1::BundleFile& file : bundle.files()) {
        fs::path target = job_dir / file.path();
        if (fs::exists(target, ec)) continue;
        fs::path asset = asset_path(file.sha256());
        if (!fs::exists(asset, ec)) fetch_asset(file.sha256(), file.size(), fetch);
        fs::create_directories(target.parent_path());
        // Link (or copy) under a temporary name, then rename over the target: atomic for other
        // workers that share this cache and may be reading the folder.
        std::string hidden(".");
        hidden += target.filename().string();
        fs::path tmp = target.parent_path() / temp_name(hidden);
        fs::create_hard_link(asset, tmp, ec);
        if (ec) fs::copy_file(asset, tmp, fs::copy_options::overwrite_existing);
        fs::rename(tmp, target);
        touch(asset);
    }
    touch(job_dir);  // its last use, which orders the prunes
    return use;
}

AssetCache::PruneResult AssetCache::prune(uint64_t budget, const std::string& keep) {
    PruneResult result;
    if (flock_retrying(lock_fd_, LOCK_EX | LOCK_NB) != 0) return result;  // in use elsewhere
    struct Unlock {
        int fd;
        ~Unlock() { flock_retrying(fd, LOCK_UN); }
    } unlock{lock_fd_};
    result.ran = true;

    CacheContents c = CacheContents::scan(dir_);
    result.bytes_before = c.bytes;
    // Nobody fetches or links while the lock is held exclusively: temporary files are
    // leftovers of a process that died.
    for (const auto& [path, key] : c.temporary) c.remove_link(path, key);

    std::error_code ec;
    auto by_use = [](const auto& a, const auto& b) { return a.used_ns < b.used_ns; };
    std::sort(c.assets.begin(), c.assets.end(), by_use);
    std::erase_if(c.jobs, [&](const CacheContents::Job& job) { return job.id == keep; });
    std::sort(c.jobs.begin(), c.jobs.end(), by_use);

    std::vector<bool> asset_gone(c.assets.size(), false);
    size_t next_job = 0;
    while (c.bytes > budget) {
        // First the oldest asset that no job folder links (only its own name is left) ...
        bool removed = false;
        for (size_t i = 0; i < c.assets.size() && !removed; ++i) {
            if (asset_gone[i] || c.inodes[c.assets[i].key].links != 1) continue;
            asset_gone[i] = true;
            if (c.remove_link(c.assets[i].path, c.assets[i].key)) {
                ++result.assets_removed;
                removed = true;
            }
        }
        if (removed) continue;
        // ... then the least recently used job folder, which may leave assets unlinked.
        if (next_job == c.jobs.size()) break;
        const CacheContents::Job& job = c.jobs[next_job++];
        for (const auto& [path, key] : job.files) c.remove_link(path, key);
        fs::remove_all(job.dir, ec);
        ++result.jobs_removed;
    }
    result.bytes_after = c.bytes;
    if (result.jobs_removed > 0 || result.assets_removed > 0)
        log_info("cache_pruned")
            .kv("jobs_removed", result.jobs_removed)
            .kv("assets_removed", result.assets_removed)
            .kv("bytes_before", result.bytes_before)
            .kv("bytes_after", result.bytes_after)
            .kv("budget_bytes", budget);
    return result;
}

uint64_t AssetCache::size_bytes() const {
    return CacheContents::scan(dir_).bytes;
}

}  // namespace render::service
