#include "service/mask_bits.h"

#include <stdexcept>

namespace render::service {

std::string pack_mask(const std::vector<uint8_t>& mask) {
    std::string packed((mask.size() + 7) / 8, '\0');
    for (size_t p = 0; p < mask.size(); ++p)
        if (mask[p]) packed[p / 8] = char(uint8_t(packed[p / 8]) | uint8_t(1u << (p % 8)));
    return packed;
}

std::vector<uint8_t> unpack_mask(std::string_view packed, size_t pixels) {
    if (packed.size() != (pixels + 7) / 8)
        throw std::invalid_argument("an active-pixel mask of " + std::to_string(packed.size()) +
                                    " bytes for " + std::to_string(pixels) + " pixels (needs " +
                                    std::to_string((pixels + 7) / 8) + ")");
    std::vector<uint8_t> mask(pixels);
    for (size_t p = 0; p < pixels; ++p) mask[p] = (uint8_t(packed[p / 8]) >> (p % 8)) & 1u;
    if (pixels % 8 != 0 && (uint8_t(packed.back()) >> (pixels % 8)) != 0)
        throw std::invalid_argument("an active-pixel mask with bits past its last pixel");
    return mask;
}

}  // namespace render::service
