#pragma once

// SHA-256 (FIPS 180-4), incremental, for content-addressed assets. No external crypto library.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace render {

class Sha256 {
  public:
    Sha256();
    void update(const void* data, size_t size);
    void update(std::string_view data) { update(data.data(), data.size()); }
    // Finishes and returns the lower-case hex digest; the object must not be updated after.
    std::string hex_digest();

  private:
    void transform(const uint8_t* block);

    std::array<uint32_t, 8> state_;
    std::array<uint8_t, 64> buffer_{};
    size_t buffer_size_ = 0;
    uint64_t total_bytes_ = 0;
};

// The lower-case hex SHA-256 of `data`.
std::string sha256_hex(std::string_view data);

// The lower-case hex SHA-256 of a file's content; `size` (optional) receives its length.
// Throws std::runtime_error when the file cannot be read.
std::string sha256_file(const std::filesystem::path& file, uint64_t* size = nullptr);

// True for 64 lower-case hex digits.
bool is_sha256_hex(std::string_view s);

}  // namespace render
