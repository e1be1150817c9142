#pragma once

// Adaptive sampling's active-pixel mask as the worker protocol carries it (proto/render.proto,
// MaskChunk): one bit per pixel, pixel p in bit p % 8 of byte p / 8, 1 = active. An eighth of
// the mask's bytes (a 1920 x 1080 mask is 259 KB), so a worker fetches it once per round.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace render::service {

// The packed bytes of `mask` (one entry per pixel, 0 or 1).
std::string pack_mask(const std::vector<uint8_t>& mask);
// The mask of `pixels` pixels from its packed bytes; throws std::invalid_argument when the
// size is not ceil(pixels / 8) bytes or a bit past the last pixel is set.
std::vector<uint8_t> unpack_mask(std::string_view packed, size_t pixels);

}  // namespace render::service
