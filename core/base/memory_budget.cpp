#include "core/base/memory_budget.h"

#include <cctype>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/util/arguments.h"

namespace render {

namespace {

thread_local SceneMemoryBudget* t_budget = nullptr;

}  // namespace

SceneMemoryBudget::SceneMemoryBudget(uint64_t limit_bytes, std::string limit_source)
    : limit_(limit_bytes), source_(std::move(limit_source)), outer_(t_budget) {
    t_budget = this;
}

SceneMemoryBudget::~SceneMemoryBudget() {
    t_budget = outer_;
}

void SceneMemoryBudget::charge(uint64_t bytes, const std::string& what) {
    charged_ = bytes > std::numeric_limits<uint64_t>::max() - charged_
                   ? std::numeric_limits<uint64_t>::max()
                   : charged_ + bytes;
    if (limit_ > 0 && charged_ > limit_)
        throw MemoryLimitExceeded(what + ": the scene needs at least " + format_bytes(charged_) +
                                      " of memory, more than the " + format_bytes(limit_) +
                                      " limit (" + source_ + ")",
                                  charged_, limit_);
}

void rethrow_scene_error(const SceneError& e, const SceneError& with_context) {
    if (const auto* memory = dynamic_cast<const MemoryLimitExceeded*>(&e))
        throw MemoryLimitExceeded(with_context.what(), memory->needed(), memory->limit());
    throw with_context;
}

void charge_scene_memory(uint64_t bytes, const std::string& what) {
    if (t_budget) t_budget->charge(bytes, what);
}

uint64_t saturating_product(uint64_t a, uint64_t b) {
    if (a != 0 && b > std::numeric_limits<uint64_t>::max() / a)
        return std::numeric_limits<uint64_t>::max();
    return a * b;
}

void charge_file_contents(const std::filesystem::path& path) {
    if (!t_budget) return;
    std::error_code ec;
    const uint64_t size = std::filesystem::file_size(path, ec);
    if (!ec) t_budget->charge(saturating_product(size, 2), path.string() + ": file contents");
}

uint64_t film_memory_bytes(uint64_t width, uint64_t height, uint64_t buffers) {
    return saturating_product(saturating_product(width, height), saturating_product(buffers, 24));
}

uint64_t available_memory_bytes() {
    std::ifstream in("/proc/meminfo");
    std::string line;
    while (std::getline(in, line)) {
        unsigned long long kib = 0;
        if (std::sscanf(line.c_str(), "MemAvailable: %llu kB", &kib) == 1)
            return saturating_product(kib, 1024);
    }
    return 0;
}

std::string format_bytes(uint64_t bytes) {
    static const char* units[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    if (bytes < 1024) return std::to_string(bytes) + " B";
    double value = double(bytes);
    int unit = -1;
    while (value >= 1024 && unit < 5) value /= 1024, ++unit;
    char text[32];
    std::snprintf(text, sizeof text, "%.1f %s", value, units[unit]);
    return text;
}

uint64_t parse_byte_size(const std::string& text) {
    size_t i = 0;
    while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
    if (i == 0 || i > 19) throw std::invalid_argument("\"" + text + "\" is not a size");
    uint64_t value = std::stoull(text.substr(0, i));
    std::string unit = text.substr(i);
    int shift = 0;
    if (!unit.empty()) {
        const std::string scales = "KMGT";
        size_t k = scales.find(char(std::toupper(static_cast<unsigned char>(unit[0]))));
        if (k != std::string::npos) {
            shift = 10 * int(k + 1);
            unit = unit.substr(1);
        }
        if (!(unit.empty() || unit == "B" || (shift && (unit == "iB" || unit == "ib"))))
            throw std::invalid_argument("\"" + text +
                                        "\" is not a size (a number with K, M, G or T)");
    }
    if (shift && value > (std::numeric_limits<uint64_t>::max() >> shift))
        throw std::invalid_argument("\"" + text + "\" is too large");
    return value << shift;
}

uint64_t parse_size_flag(const std::string& flag, const std::string& text) {
    uint64_t v = 0;
    try {
        v = parse_byte_size(text);
    } catch (const std::invalid_argument& e) {
        throw UsageError(flag + ": " + e.what());
    }
    if (v == 0) throw UsageError(flag + " must be > 0");
    return v;
}

}  // namespace render
