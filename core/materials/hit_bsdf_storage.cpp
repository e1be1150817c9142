#include "core/materials/hit_bsdf_storage.h"

#include <array>

namespace render::hit_bsdf_storage {

namespace {

constexpr std::size_t kClassBytes = 32;
constexpr std::size_t kClasses = kLargestPooledBytes / kClassBytes;

struct FreeBlock {
    FreeBlock* next;
};

// Trivially destructible, so a block freed while the thread's other thread_locals are being
// destroyed (a shared pointer held by one of them) still finds it: after the cache's owner
// below has emptied it, `gone` sends such blocks to the heap.
struct Cache {
    std::array<FreeBlock*, kClasses> heads{};
    std::size_t bytes = 0;
    bool gone = false;
};

thread_local Cache cache;

void release_all() noexcept {
    for (std::size_t c = 0; c < kClasses; ++c)
        while (FreeBlock* b = cache.heads[c]) {
            cache.heads[c] = b->next;
            ::operator delete(static_cast<void*>(b));
        }
    cache.bytes = 0;
}

// Empties the cache when the thread ends; constructed (and its destructor registered) when
// the thread caches its first block.
struct CacheOwner {
    ~CacheOwner() {
        release_all();
        cache.gone = true;
    }
};

void own_cache() {
    static thread_local CacheOwner owner;
}

std::size_t size_class(std::size_t bytes) {
    return (bytes + kClassBytes - 1) / kClassBytes - 1;
}

}  // namespace

void* allocate(std::size_t bytes) {
    if (bytes == 0 || bytes > kLargestPooledBytes || cache.gone) return ::operator new(bytes);
    const std::size_t c = size_class(bytes);
    if (FreeBlock* b = cache.heads[c]) {
        cache.heads[c] = b->next;
        cache.bytes -= (c + 1) * kClassBytes;
        return b;
    }
    return ::operator new((c + 1) * kClassBytes);
}

void deallocate(void* block, std::size_t bytes) noexcept {
    if (bytes == 0 || bytes > kLargestPooledBytes || cache.gone) {
        ::operator delete(block);
        return;
    }
    const std::size_t c = size_class(bytes);
    const std::size_t class_bytes = (c + 1) * kClassBytes;
    if (cache.bytes + class_bytes > kMaxCachedBytesPerThread) {
        ::operator delete(block);
        return;
    }
    if (cache.bytes == 0) own_cache();
    auto* b = static_cast<FreeBlock*>(block);
    b->next = cache.heads[c];
    cache.heads[c] = b;
    cache.bytes += class_bytes;
}

std::size_t cached_bytes_this_thread() {
    return cache.bytes;
}

}  // namespace render::hit_bsdf_storage
