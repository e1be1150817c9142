#pragma once

// Storage for the BSDFs that a textured material builds at each hit (textured_bsdf.h). They are
// owned by shared pointers (a stored light vertex keeps its hit's BSDF alive after the
// interaction is gone), but their memory comes from a per-thread cache of freed blocks instead
// of the heap: after the first hits of a thread, building a hit's BSDF allocates nothing. A
// block freed on another thread joins that thread's cache. Blocks are grouped by size (32-byte
// classes up to kLargestPooledBytes; larger ones use the heap), and each thread keeps at most
// kMaxCachedBytesPerThread of freed blocks, returning the rest to the heap (a thread that clears
// an iteration's light vertices frees far more than it builds).

#include <cstddef>
#include <memory>
#include <new>
#include <utility>

#include "core/math/vec.h"

namespace render {

namespace hit_bsdf_storage {

inline constexpr std::size_t kLargestPooledBytes = 512;
inline constexpr std::size_t kMaxCachedBytesPerThread = std::size_t{8} << 20;

void* allocate(std::size_t bytes);
void deallocate(void* block, std::size_t bytes) noexcept;

// The thread's cached bytes (tests).
std::size_t cached_bytes_this_thread();

}  // namespace hit_bsdf_storage

// The allocator std::allocate_shared uses for a hit's BSDF (its object and reference counts
// in one block).
template <class T>
struct HitBsdfAllocator {
    using value_type = T;
    HitBsdfAllocator() = default;
    template <class U>
    HitBsdfAllocator(const HitBsdfAllocator<U>&) noexcept {}

    T* allocate(std::size_t n) {
        static_assert(alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__,
                      "the blocks have operator new's alignment");
        return static_cast<T*>(hit_bsdf_storage::allocate(n * sizeof(T)));
    }
    void deallocate(T* p, std::size_t n) noexcept {
        hit_bsdf_storage::deallocate(p, n * sizeof(T));
    }
    template <class U>
    bool operator==(const HitBsdfAllocator<U>&) const noexcept {
        return true;
    }
    template <class U>
    bool operator!=(const HitBsdfAllocator<U>&) const noexcept {
        return false;
    }
};

// A material's BSDF from its parameters at `uv`: built for one hit (from the per-thread storage)
// when uv is given, the scene's own (on the heap, for the scene's lifetime) when it is null.
template <class T, class... Args>
std::shared_ptr<T> make_bsdf_at(const Vec2* uv, Args&&... args) {
    if (uv) return std::allocate_shared<T>(HitBsdfAllocator<T>(), std::forward<Args>(args)...);
    return std::make_shared<T>(std::forward<Args>(args)...);
}

}  // namespace render
