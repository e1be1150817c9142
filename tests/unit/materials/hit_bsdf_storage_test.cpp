// The per-thread storage of the BSDFs built at each hit of a textured material
// (core/materials/hit_bsdf_storage.h): a freed block is reused for the next BSDF of its size
// class on the same thread (no heap allocation once a thread has warmed up), a BSDF freed on
// another thread joins that thread's cache, sizes above the pooled ones and caches beyond their
// bound go to the heap, and a hit's BSDF stays valid while a shared pointer holds it.

#include <gtest/gtest.h>

#include <memory>
#include <thread>
#include <vector>

#include "core/materials/diffuse.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/math/constants.h"

namespace render {
namespace {

const Vec2 kUv(0.25f, 0.75f);

TEST(HitBsdfStorage, AFreedBlockIsReusedByTheNextBsdfOfItsSize) {
    const void* first;
    {
        std::shared_ptr<DiffuseBsdf> a = make_bsdf_at<DiffuseBsdf>(&kUv, Rgb(0.5f));
        first = a.get();
    }
    const size_t cached = hit_bsdf_storage::cached_bytes_this_thread();
    EXPECT_GT(cached, 0u);
    std::shared_ptr<DiffuseBsdf> b = make_bsdf_at<DiffuseBsdf>(&kUv, Rgb(0.25f));
    EXPECT_EQ(b.get(), first);
    EXPECT_LT(hit_bsdf_storage::cached_bytes_this_thread(), cached);
    EXPECT_FLOAT_EQ(b->f(Vec3(0, 0, 1), Vec3(0, 0, 1), TransportMode::Radiance).r, 0.25f / kPi);
}

TEST(HitBsdfStorage, WithoutAUvTheBsdfIsTheScenesOwnAndNotCached) {
    const size_t cached = hit_bsdf_storage::cached_bytes_this_thread();
    { std::shared_ptr<DiffuseBsdf> a = make_bsdf_at<DiffuseBsdf>(nullptr, Rgb(0.5f)); }
    EXPECT_EQ(hit_bsdf_storage::cached_bytes_this_thread(), cached);
}

TEST(HitBsdfStorage, ABsdfFreedOnAnotherThreadJoinsThatThreadsCache) {
    std::shared_ptr<DiffuseBsdf> a = make_bsdf_at<DiffuseBsdf>(&kUv, Rgb(0.5f));
    size_t before = 0, after = 0;
    std::thread other([&] {
        before = hit_bsdf_storage::cached_bytes_this_thread();
        a.reset();
        after = hit_bsdf_storage::cached_bytes_this_thread();
    });
    other.join();
    EXPECT_EQ(before, 0u);
    EXPECT_GT(after, 0u);
}

TEST(HitBsdfStorage, LargeBlocksAndBlocksBeyondTheBoundUseTheHeap) {
    const size_t cached = hit_bsdf_storage::cached_bytes_this_thread();
    void* large = hit_bsdf_storage::allocate(hit_bsdf_storage::kLargestPooledBytes + 1);
    hit_bsdf_storage::deallocate(large, hit_bsdf_storage::kLargestPooledBytes + 1);
    EXPECT_EQ(hit_bsdf_storage::cached_bytes_this_thread(), cached);

    // Free more than the bound in one go: the cache stops at the bound.
    std::thread filler([] {
        std::vector<void*> blocks;
        const size_t size = 256;
        const size_t count = hit_bsdf_storage::kMaxCachedBytesPerThread / size + 100;
        for (size_t i = 0; i < count; ++i) blocks.push_back(hit_bsdf_storage::allocate(size));
        for (void* b : blocks) hit_bsdf_storage::deallocate(b, size);
        EXPECT_LE(hit_bsdf_storage::cached_bytes_this_thread(),
                  hit_bsdf_storage::kMaxCachedBytesPerThread);
        EXPECT_GT(hit_bsdf_storage::cached_bytes_this_thread(),
                  hit_bsdf_storage::kMaxCachedBytesPerThread - size);
    });
    filler.join();
}

TEST(HitBsdfStorage, AHitBsdfOutlivesTheThreadThatBuiltIt) {
    std::shared_ptr<const Bsdf> kept;
    std::thread builder([&] { kept = make_bsdf_at<DiffuseBsdf>(&kUv, Rgb(0.5f)); });
    builder.join();
    ASSERT_TRUE(kept);
    EXPECT_FLOAT_EQ(kept->f(Vec3(0, 0, 1), Vec3(0, 0, 1), TransportMode::Radiance).g, 0.5f / kPi);
    kept.reset();  // freed into this thread's cache
    EXPECT_GT(hit_bsdf_storage::cached_bytes_this_thread(), 0u);
}

}  // namespace
}  // namespace render
