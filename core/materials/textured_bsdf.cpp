#include "core/materials/textured_bsdf.h"

#include <stdexcept>

namespace render {

TexturedBsdf::TexturedBsdf(Builder build, std::shared_ptr<const Bsdf> typical,
                           std::string description)
    : build_(std::move(build)), typical_(std::move(typical)), description_(std::move(description)) {
    if (!build_ || !typical_)
        throw std::invalid_argument("TexturedBsdf needs a builder and a BSDF");
    varies_ = true;
}

std::shared_ptr<const Bsdf> TexturedBsdf::at(Vec2 uv) const {
    std::shared_ptr<Bsdf> bsdf = build_(uv);
    bsdf->built_for_hit_ = true;
    return bsdf;
}

}  // namespace render
