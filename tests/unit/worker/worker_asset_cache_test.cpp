// The worker's asset cache (worker/asset_cache.h): bundles materialized from content-addressed
// assets, and the size bound that prunes least recently used job folders and assets first,
// never the job in use and never while another worker holds the cache.

#include "worker/asset_cache.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "core/util/sha256.h"

namespace render::service {
namespace {

namespace fs = std::filesystem;

// A folder under the system's temporary directory, removed at the end of the test.
struct TempDir {
    fs::path path;
    TempDir() {
        path = fs::temp_directory_path() /
               ("asset-cache-test-" + std::to_string(getpid()) + "-" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(path);
        fs::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

// The server's side: the assets by hash, and how many times each was fetched.
struct FakeServer {
    std::map<std::string, std::string> assets;
    std::map<std::string, int> fetches;
    std::map<std::string, std::string> corrupt;  // sha256 -> what arrives instead

    v1::SceneBundle bundle(const std::map<std::string, std::string>& files,
                           const std::string& scene_path) {
        v1::SceneBundle b;
        b.set_scene_path(scene_path);
        for (const auto& [path, data] : files) {
            const std::string sha = sha256_hex(data);
            assets[sha] = data;
            v1::BundleFile* f = b.add_files();
            f->set_path(path);
            f->set_sha256(sha);
            f->set_size(data.size());
        }
        return b;
    }
    AssetCache::Fetcher fetcher() {
        return [this](const std::string& sha, const std::function<void(const std::string&)>& sink) {
            ++fetches[sha];
            auto bad = corrupt.find(sha);
            sink(bad != corrupt.end() ? bad->second : assets.at(sha));
            return grpc::Status::OK;
        };
    }
};

std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// Time stamps order the prunes; some file systems keep them at a few milliseconds'
// resolution, so uses that must be ordered are this far apart.
void next_tick() {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
}

const std::string kScene = "<scene version=\"3.0.0\"/>";

// A job whose bundle is the shared scene file and one asset of `bytes` bytes of its own.
v1::SceneBundle job_bundle(FakeServer& server, char fill, size_t bytes) {
    return server.bundle({{"scene.xml", kScene}, {"data/own.bin", std::string(bytes, fill)}},
                         "scene.xml");
}

TEST(AssetCache, PrepareJobBuildsTheBundleFolderAndFetchesEachAssetOnce) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path);
    const v1::SceneBundle a = job_bundle(server, 'a', 1000), b = job_bundle(server, 'b', 700);
    {
        AssetCache::Use use = cache.prepare_job("job-a", a, server.fetcher());
        EXPECT_EQ(use.scene_file(), dir.path / "jobs" / "job-a" / "scene.xml");
        EXPECT_EQ(read(use.scene_file()), kScene);
        EXPECT_EQ(read(dir.path / "jobs" / "job-a" / "data" / "own.bin"), std::string(1000, 'a'));
    }
    cache.prepare_job("job-a", a, server.fetcher());  // again: nothing fetched
    cache.prepare_job("job-b", b, server.fetcher());  // shares the scene file
    EXPECT_EQ(server.fetches[sha256_hex(kScene)], 1);
    EXPECT_EQ(server.fetches[sha256_hex(std::string(1000, 'a'))], 1);
    EXPECT_EQ(server.fetches[sha256_hex(std::string(700, 'b'))], 1);
    // Hard links: each file's bytes once.
    EXPECT_EQ(cache.size_bytes(), kScene.size() + 1000 + 700);
}

TEST(AssetCache, ACorruptedAssetIsRefusedAndLeavesNothingBehind) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path);
    const v1::SceneBundle a = job_bundle(server, 'a', 1000);
    const std::string sha = sha256_hex(std::string(1000, 'a'));
    server.corrupt[sha] = std::string(1000, 'x');
    EXPECT_THROW(cache.prepare_job("job-a", a, server.fetcher()), std::runtime_error);
    EXPECT_FALSE(fs::exists(cache.asset_path(sha)));
    EXPECT_TRUE(fs::is_empty(dir.path / "tmp"));
}

TEST(AssetCache, ABoundedCacheRemovesTheLeastRecentlyUsedJobAndItsAssetsFirst) {
    TempDir dir;
    FakeServer server;
    // Three jobs of ~1 kB each do not fit in 2.5 kB: the third makes room by removing the job
    // used longest ago (job-b: job-a was used again after it), with the asset only it had.
    AssetCache cache(dir.path, 2500);
    const v1::SceneBundle a = job_bundle(server, 'a', 1000), b = job_bundle(server, 'b', 1000),
                          c = job_bundle(server, 'c', 1000);
    cache.prepare_job("job-a", a, server.fetcher());
    next_tick();
    cache.prepare_job("job-b", b, server.fetcher());
    next_tick();
    cache.prepare_job("job-a", a, server.fetcher());
    next_tick();
    cache.prepare_job("job-c", c, server.fetcher());

    EXPECT_FALSE(fs::exists(dir.path / "jobs" / "job-b"));
    EXPECT_FALSE(fs::exists(cache.asset_path(sha256_hex(std::string(1000, 'b')))));
    EXPECT_TRUE(fs::exists(dir.path / "jobs" / "job-a" / "data" / "own.bin"));
    EXPECT_TRUE(fs::exists(dir.path / "jobs" / "job-c" / "data" / "own.bin"));
    EXPECT_TRUE(fs::exists(cache.asset_path(sha256_hex(kScene))));  // job-a and job-c link it
    EXPECT_LE(cache.size_bytes(), 2500u);
    EXPECT_EQ(cache.size_bytes(), kScene.size() + 2000);

    // job-b again: its asset is fetched a second time, and job-a (used before job-c) goes.
    next_tick();
    cache.prepare_job("job-b", b, server.fetcher());
    EXPECT_EQ(server.fetches[sha256_hex(std::string(1000, 'b'))], 2);
    EXPECT_FALSE(fs::exists(dir.path / "jobs" / "job-a"));
    EXPECT_TRUE(fs::exists(dir.path / "jobs" / "job-c"));
    EXPECT_LE(cache.size_bytes(), 2500u);
}

TEST(AssetCache, UnlinkedAssetsGoBeforeAnyJobFolder) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path);
    cache.prepare_job("job-a", job_bundle(server, 'a', 1000), server.fetcher());
    next_tick();
    cache.prepare_job("job-b", job_bundle(server, 'b', 1000), server.fetcher());
    // An asset no job folder links (its job's folder went, say), used more recently than both.
    next_tick();
    const std::string loose(800, 'l');
    {
        std::ofstream out(cache.asset_path(sha256_hex(loose)), std::ios::binary);
        out << loose;
    }
    const AssetCache::PruneResult r = cache.prune(cache.size_bytes() - 1, "");
    EXPECT_TRUE(r.ran);
    EXPECT_EQ(r.assets_removed, 1);
    EXPECT_EQ(r.jobs_removed, 0);
    EXPECT_FALSE(fs::exists(cache.asset_path(sha256_hex(loose))));
    EXPECT_EQ(r.bytes_after, kScene.size() + 2000);
}

TEST(AssetCache, PruningKeepsTheJobInUseAndWaitsForOtherWorkersUsingTheCache) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path), other_worker(dir.path);
    cache.prepare_job("job-a", job_bundle(server, 'a', 1000), server.fetcher());
    next_tick();
    cache.prepare_job("job-b", job_bundle(server, 'b', 1000), server.fetcher());
    const uint64_t full = cache.size_bytes();
    {
        // Another worker sharing the folder is preparing or loading job-b: nothing is pruned.
        AssetCache::Use in_use =
            other_worker.prepare_job("job-b", job_bundle(server, 'b', 1000), server.fetcher());
        const AssetCache::PruneResult r = cache.prune(0, "");
        EXPECT_FALSE(r.ran);
        EXPECT_EQ(cache.size_bytes(), full);
    }
    // Released: everything but the kept job goes (budget 0 cannot be met while it stays).
    const AssetCache::PruneResult r = cache.prune(0, "job-b");
    EXPECT_TRUE(r.ran);
    EXPECT_EQ(r.jobs_removed, 1);
    EXPECT_EQ(r.assets_removed, 1);  // job-a's own asset; the scene file job-b links stays
    EXPECT_FALSE(fs::exists(dir.path / "jobs" / "job-a"));
    EXPECT_EQ(read(dir.path / "jobs" / "job-b" / "data" / "own.bin"), std::string(1000, 'b'));
    EXPECT_EQ(r.bytes_after, kScene.size() + 1000);
}

TEST(AssetCache, AJobLargerThanTheBoundStillRendersAndTheCacheHoldsOnlyIt) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path, 500);
    cache.prepare_job("job-a", job_bundle(server, 'a', 1000), server.fetcher());
    next_tick();
    AssetCache::Use use =
        cache.prepare_job("job-b", job_bundle(server, 'b', 2000), server.fetcher());
    EXPECT_EQ(read(use.scene_file()), kScene);
    EXPECT_FALSE(fs::exists(dir.path / "jobs" / "job-a"));
    EXPECT_EQ(cache.size_bytes(), kScene.size() + 2000);
}

TEST(AssetCache, WithoutABoundNothingIsRemoved) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path, 0);
    for (char fill : std::string("abcdef")) {
        cache.prepare_job(std::string("job-") + fill, job_bundle(server, fill, 1000),
                          server.fetcher());
        next_tick();
    }
    EXPECT_EQ(cache.size_bytes(), kScene.size() + 6000);
    for (char fill : std::string("abcdef"))
        EXPECT_TRUE(fs::exists(dir.path / "jobs" / (std::string("job-") + fill)));
}

TEST(AssetCache, PruningRemovesTemporaryFilesADeadWorkerLeft) {
    TempDir dir;
    FakeServer server;
    AssetCache cache(dir.path);
    cache.prepare_job("job-a", job_bundle(server, 'a', 1000), server.fetcher());
    {
        std::ofstream out(dir.path / "tmp" / "deadbeef.123.1.tmp", std::ios::binary);
        out << std::string(300, 'z');
    }
    EXPECT_EQ(cache.size_bytes(), kScene.size() + 1300);
    const AssetCache::PruneResult r = cache.prune(uint64_t(1) << 40, "");
    EXPECT_TRUE(r.ran);
    EXPECT_TRUE(fs::is_empty(dir.path / "tmp"));
    EXPECT_EQ(r.bytes_after, kScene.size() + 1000);
    EXPECT_EQ(r.jobs_removed, 0);
}

}  // namespace
}  // namespace render::service
