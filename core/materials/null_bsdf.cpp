#include "core/materials/null_bsdf.h"

namespace render {

std::shared_ptr<const Bsdf> NullBsdf::create(const Properties&) {
    return std::make_shared<NullBsdf>();
}

std::optional<BsdfSample> NullBsdf::sample(const Vec3& wo, float, Vec2, TransportMode) const {
    BsdfSample s;
    s.wi = -wo;
    s.weight = Rgb(1.0f);
    s.pdf_w = BsdfPdf{1.0f, 1.0f};  // discrete, like every delta lobe (bsdf.h)
    s.delta = true;
    s.lobe = kLobeNull;
    return s;
}

}  // namespace render
