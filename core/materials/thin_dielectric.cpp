#include "core/materials/thin_dielectric.h"

#include <cmath>
#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {

ThinDielectricBsdf::ThinDielectricBsdf(float eta, const Rgb& specular_reflectance,
                                       const Rgb& specular_transmission)
    : eta_(eta),
      specular_reflectance_(specular_reflectance),
      specular_transmission_(specular_transmission) {}

std::shared_ptr<const Bsdf> ThinDielectricBsdf::create(const Properties& props) {
    const float eta = read_relative_ior(props, *lookup_dielectric_ior("bk7"));
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    const RgbParam kt = read_reflectance_param(props, "specular_transmission", Rgb(1.0f));
    return plain_or_textured(ks.varies() || kt.varies(), [eta, ks, kt](const Vec2* uv) {
        return make_bsdf_at<ThinDielectricBsdf>(uv, eta, ks.at(uv), kt.at(uv));
    });
}

float ThinDielectricBsdf::slab_reflectance(float cos_theta) const {
    const float r = fresnel_dielectric(std::abs(cos_theta), eta_).reflectance;
    // Total internal reflection at the first interface (eta < 1, from outside): no light
    // enters the slab.
    if (!(r < 1.0f)) return 1.0f;
    const float t = 1.0f - r;
    return std::min(1.0f, r + t * t * r / (1.0f - r * r));
}

std::optional<BsdfSample> ThinDielectricBsdf::sample(const Vec3& wo, float u_lobe, Vec2,
                                                     TransportMode) const {
    if (wo.z == 0 || !is_finite(wo)) return std::nullopt;
    const float reflectance = slab_reflectance(wo.z);
    BsdfSample s;
    s.delta = true;
    s.eta = 1.0f;
    if (u_lobe < reflectance) {
        s.wi = reflect_z(wo);
        s.weight = specular_reflectance_;
        s.pdf_w = {reflectance, reflectance};
        s.lobe = kLobeDeltaReflection;
        return s;
    }
    // Straight through: the same |cos theta| on the other side, hence the same probability
    // in reverse.
    s.wi = -wo;
    s.weight = specular_transmission_;
    s.pdf_w = {1.0f - reflectance, 1.0f - reflectance};
    s.lobe = kLobeDeltaTransmission;
    return s;
}

std::string ThinDielectricBsdf::to_string() const {
    std::ostringstream out;
    out << "thindielectric(eta " << eta_ << ", specular_reflectance " << specular_reflectance_
        << ", specular_transmission " << specular_transmission_ << ")";
    return out.str();
}

}  // namespace render
