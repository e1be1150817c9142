#include "server/report_values.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "server/write_all.h"

namespace render::server {

namespace {

std::string system_error(const std::string& what) {
    return what + ": " + std::strerror(errno);
}

// An unlinked file in `dir`: O_TMPFILE where the file system has it (the file never has a
// name), else a named file unlinked at once.
int open_unlinked(const std::filesystem::path& dir) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec)
        throw std::runtime_error("cannot make the report spool folder " + dir.string() + ": " +
                                 ec.message());
    int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd >= 0) return fd;
    std::string name = (dir / "report-XXXXXX").string();
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd < 0)
        throw std::runtime_error(
            system_error("cannot make a report spool file in " + dir.string()));
    ::unlink(name.c_str());
    return fd;
}

}  // namespace

ReportValues ReportValues::in_memory(size_t count, Words words) {
    ReportValues v;
    v.count_ = count;
    v.words_ = words;
    // Not zeroed (a pass over up to a whole frame's sums): every value is written by the
    // stream before it is read, which complete() checks.
    v.memory_.reset(new double[count]);
    return v;
}

ReportValues ReportValues::spooled(const std::filesystem::path& dir, size_t count, Words words) {
    ReportValues v;
    v.count_ = count;
    v.words_ = words;
    v.dir_ = dir;
    v.fd_ = open_unlinked(dir);
    return v;
}

ReportValues::ReportValues(ReportValues&& other) noexcept {
    *this = std::move(other);
}

ReportValues& ReportValues::operator=(ReportValues&& other) noexcept {
    if (this == &other) return *this;
    release();
    count_ = std::exchange(other.count_, 0);
    words_ = other.words_;
    received_ = std::exchange(other.received_, 0);
    memory_ = std::move(other.memory_);
    fd_ = std::exchange(other.fd_, -1);
    dir_ = std::move(other.dir_);
    std::memcpy(partial_, other.partial_, sizeof partial_);
    return *this;
}

ReportValues::~ReportValues() {
    release();
}

void ReportValues::release() {
    memory_.reset();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    count_ = 0;
    received_ = 0;
}

std::string ReportValues::check(size_t index, const char* bytes) const {
    if (index < words_.from) {
        double value;
        std::memcpy(&value, bytes, sizeof value);
        if (!std::isfinite(value))
            return "report value " + std::to_string(index) + " is not finite";
        return "";
    }
    int64_t word;
    std::memcpy(&word, bytes, sizeof word);
    if (word < 0 || word > words_.max)
        return "report exact sum " + std::to_string(index - words_.from) + " is " +
               std::to_string(word) + ", outside [0, " + std::to_string(words_.max) + "]";
    return "";
}

std::string ReportValues::append(std::string_view bytes, bool* spool_failed) {
    const size_t expected = count_ * sizeof(double);
    if (bytes.size() > expected - received_)
        return "report has more than the expected " + std::to_string(expected) + " bytes of values";
    const size_t begin = received_;
    if (memory_) {
        std::memcpy(reinterpret_cast<char*>(memory_.get()) + begin, bytes.data(), bytes.size());
        received_ += bytes.size();
        const char* base = reinterpret_cast<const char*>(memory_.get());
        for (size_t i = begin / sizeof(double); i < received_ / sizeof(double); ++i)
            if (std::string e = check(i, base + i * sizeof(double)); !e.empty()) return e;
        return "";
    }
    if (!write_all(fd_, bytes.data(), bytes.size())) {
        if (spool_failed) *spool_failed = true;
        return system_error("cannot spool the report to " + dir_.string());
    }
    received_ += bytes.size();
    // Check each value whose last byte arrived: first the value split by the previous chunk,
    // completed from the bytes kept in partial_, then the chunk's whole values, then keep the
    // first bytes of one it splits.
    const char* data = bytes.data();
    const char* const data_end = data + bytes.size();
    size_t index = begin / sizeof(double);
    if (const size_t have = begin % sizeof(double); have > 0) {
        const size_t take = std::min(sizeof(double) - have, bytes.size());
        std::memcpy(partial_ + have, data, take);
        data += take;
        if (have + take < sizeof(double)) return "";
        if (std::string e = check(index, partial_); !e.empty()) return e;
        ++index;
    }
    for (; data_end - data >= ptrdiff_t(sizeof(double)); data += sizeof(double), ++index)
        if (std::string e = check(index, data); !e.empty()) return e;
    std::memcpy(partial_, data, size_t(data_end - data));
    return "";
}

std::span<const double> ReportValues::block(size_t first, size_t n,
                                            std::vector<double>& scratch) const {
    if (first > received_ / sizeof(double) || n > received_ / sizeof(double) - first)
        throw std::out_of_range("report values " + std::to_string(first) + " + " +
                                std::to_string(n) + " were not received");
    if (memory_) return {memory_.get() + first, n};
    scratch.resize(n);
    char* out = reinterpret_cast<char*>(scratch.data());
    const size_t size = n * sizeof(double);
    for (size_t done = 0; done < size;) {
        const ssize_t r =
            ::pread(fd_, out + done, size - done, off_t((first * sizeof(double)) + done));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0)
            throw std::runtime_error(
                system_error("cannot read the report spooled in " + dir_.string()));
        done += size_t(r);
    }
    return scratch;
}

}  // namespace render::server
