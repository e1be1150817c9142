#pragma once

// How much memory one scene may take on this machine: a scene that needs more memory than a
// worker has fails its job with a message instead of the kernel killing the worker
// (docs/guide/reliability.md, "The memory budget").
//
// A SceneMemoryBudget, set for the duration of a load on the loading thread, is charged by the
// loaders with the size of each large buffer before it is allocated (file contents, meshes and
// their acceleration structure, grids, images) and by the caller with the render's buffers.
// Without a budget (the `render` command) charges cost nothing and never fail.

#include <cstdint>
#include <filesystem>
#include <string>

#include "core/base/error.h"

namespace render {

// A scene that would need more memory than its budget allows: a SceneError naming what was
// being loaded, the estimate so far and the limit with where it comes from.
class MemoryLimitExceeded : public SceneError {
  public:
    using SceneError::SceneError;
    MemoryLimitExceeded(const std::string& message, uint64_t needed, uint64_t limit)
        : SceneError(message), needed_(needed), limit_(limit) {}
    // The estimate when the limit was passed (a lower bound of what the scene needs) and the
    // limit; 0 when thrown without them.
    uint64_t needed() const { return needed_; }
    uint64_t limit() const { return limit_; }

  private:
    uint64_t needed_ = 0, limit_ = 0;
};

// Throws `with_context` (e with the caller's file, line or field added) in place of `e`: a
// MemoryLimitExceeded stays one, with its numbers, so that a worker tells a refusal for memory
// (which the server does not count against the job) from a scene that cannot load.
[[noreturn]] void rethrow_scene_error(const SceneError& e, const SceneError& with_context);

class SceneMemoryBudget {
  public:
    // `limit_bytes` 0 means no limit. `limit_source` says where the limit comes from, for the
    // message ("worker --max-memory", "available memory (/proc/meminfo MemAvailable)").
    SceneMemoryBudget(uint64_t limit_bytes, std::string limit_source);
    ~SceneMemoryBudget();
    SceneMemoryBudget(const SceneMemoryBudget&) = delete;
    SceneMemoryBudget& operator=(const SceneMemoryBudget&) = delete;

    // Adds `bytes` to the estimate; throws MemoryLimitExceeded ("WHAT: the scene needs at least
    // N MiB of memory, more than the M MiB limit (SOURCE)") if the total exceeds the limit.
    void charge(uint64_t bytes, const std::string& what);
    uint64_t charged() const { return charged_; }
    uint64_t limit() const { return limit_; }

  private:
    uint64_t limit_;
    std::string source_;
    uint64_t charged_ = 0;
    SceneMemoryBudget* outer_;  // budgets nest per thread; the innermost one is charged
};

// Charges the innermost budget of this thread, if any (the loaders call this).
void charge_scene_memory(uint64_t bytes, const std::string& what);

// Charges a file's contents, read whole into memory to be parsed: twice its size (a stream
// read copies it once more). Nothing if the size cannot be read (the read will say why).
void charge_file_contents(const std::filesystem::path& path);

// The bytes of `buffers` full-frame sums of 3 doubles per pixel (what the film costs a worker
// or the server per frame, besides the scene).
uint64_t film_memory_bytes(uint64_t width, uint64_t height, uint64_t buffers);

// a * b, saturating at UINT64_MAX instead of wrapping (sizes from untrusted headers).
uint64_t saturating_product(uint64_t a, uint64_t b);

// /proc/meminfo's MemAvailable in bytes (0 where unknown).
uint64_t available_memory_bytes();

// "1.5 GiB", "12.0 MiB", "512 B".
std::string format_bytes(uint64_t bytes);

// Parses a size for a command-line option: a number with an optional K, M, G or T suffix
// (powers of 1024; "B" or "iB" may follow). Throws std::invalid_argument on anything else.
uint64_t parse_byte_size(const std::string& text);

// parse_byte_size for the value of option `flag` (--max-memory, ...), which must be > 0.
// Throws UsageError naming the flag.
uint64_t parse_size_flag(const std::string& flag, const std::string& text);

}  // namespace render
