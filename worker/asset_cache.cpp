#include "worker/asset_cache.h"

#include <unistd.h>

#include <fstream>
#include <stdexcept>
#include <system_error>

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

AssetCache::AssetCache(fs::path dir) : dir_(std::move(dir)) {
    fs::create_directories(dir_ / "assets");
    fs::create_directories(dir_ / "jobs");
    fs::create_directories(dir_ / "tmp");
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

fs::path AssetCache::prepare_job(const std::string& job_id, const v1::SceneBundle& bundle,
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
    if (prepared_jobs_.count(job_id)) return job_dir / bundle.scene_path();

    for (const v1::BundleFile& file : bundle.files()) {
        fs::path asset = asset_path(file.sha256());
        std::error_code ec;
        if (!fs::exists(asset, ec)) fetch_asset(file.sha256(), file.size(), fetch);
        fs::path target = job_dir / file.path();
        fs::create_directories(target.parent_path());
        // Link (or copy) under a temporary name, then rename over the target: atomic for other
        // workers that share this cache and may be reading the folder.
        std::string hidden(".");
        hidden += target.filename().string();
        fs::path tmp = target.parent_path() / temp_name(hidden);
        fs::create_hard_link(asset, tmp, ec);
        if (ec) fs::copy_file(asset, tmp, fs::copy_options::overwrite_existing);
        fs::rename(tmp, target);
    }
    prepared_jobs_.insert(job_id);
    return job_dir / bundle.scene_path();
}

}  // namespace render::service
