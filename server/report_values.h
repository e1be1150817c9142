#pragma once

// A report's float64 values as they arrive over its stream: `sum`, `odd_sum` unless the header
// omits it, then the layers' sums, one sequence. They are held until the last byte, so that a
// report that fails half-way changes nothing, and merged only then.
//
// A small report is held in memory. A large one is spooled: written, as it arrives, to an
// unlinked file in the store's spool folder, and read back in blocks while it is merged. A
// report of several iterations carries `sum` and `odd_sum`, as large as the frame's merged sums
// themselves (400 MB at 3840x2160): in memory a running frame would cost twice its sums;
// spooled it costs its sums plus two blocks. The file's pages are the kernel's page cache, which
// it may write out under memory pressure; the file disappears when the report is merged or
// dropped, and with the process if it dies.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace render::server {

// The values from index `from` on are not float64 but little-endian int64 words (an
// adaptive job's exact sums, proto/render.proto), each checked to lie in [0, max] instead
// of being finite. block() returns them as 8-byte values: copy them out with memcpy.
struct ReportWords {
    size_t from = SIZE_MAX;
    int64_t max = 0;
};

class ReportValues {
  public:
    using Words = ReportWords;

    // `count` values to receive, held in memory.
    static ReportValues in_memory(size_t count, Words words = {});
    // `count` values to receive, spooled to an unlinked file in `dir` (made if missing). Throws
    // std::runtime_error naming the folder when no such file can be made.
    static ReportValues spooled(const std::filesystem::path& dir, size_t count, Words words = {});

    ReportValues(ReportValues&& other) noexcept;
    ReportValues& operator=(ReportValues&& other) noexcept;
    ReportValues(const ReportValues&) = delete;
    ReportValues& operator=(const ReportValues&) = delete;
    ~ReportValues();

    size_t count() const { return count_; }
    size_t received_bytes() const { return received_; }
    bool complete() const { return received_ == count_ * sizeof(double); }
    bool is_spooled() const { return fd_ >= 0; }

    // Appends the stream's next bytes (a value may be split between two calls). Returns what is
    // wrong, or "" when nothing is: more bytes than count() values, a value that is not finite
    // or a word out of its range (checked as soon as its last byte arrives, named by its
    // index), or a write to the spool
    // file that failed, which sets `*spool_failed` (the server's fault, not the report's).
    std::string append(std::string_view bytes, bool* spool_failed = nullptr);

    // Values [first, first + n) of the sequence: a view of the memory, or read from the spool
    // file into `scratch`. Throws std::runtime_error when the file cannot be read, and
    // std::out_of_range past the values received.
    std::span<const double> block(size_t first, size_t n, std::vector<double>& scratch) const;

    // Frees the memory or closes (and so deletes) the spool file: count() becomes 0.
    void release();

  private:
    ReportValues() = default;
    // What is wrong with value `index` (its 8 bytes at `bytes`), or "".
    std::string check(size_t index, const char* bytes) const;

    size_t count_ = 0;
    Words words_;
    size_t received_ = 0;
    std::unique_ptr<double[]> memory_;   // in memory
    int fd_ = -1;                        // spooled
    std::filesystem::path dir_;          // spooled: for messages
    char partial_[sizeof(double)] = {};  // spooled: the first bytes of a value split by chunks
};

}  // namespace render::server
