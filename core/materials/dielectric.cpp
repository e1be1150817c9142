#include "core/materials/dielectric.h"

#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {

DielectricBsdf::DielectricBsdf(float eta, const Rgb& specular_reflectance,
                               const Rgb& specular_transmission)
    : eta_(eta),
      specular_reflectance_(specular_reflectance),
      specular_transmission_(specular_transmission) {}

std::shared_ptr<const Bsdf> DielectricBsdf::create(const Properties& props) {
    const float eta = read_relative_ior(props, *lookup_dielectric_ior("bk7"));
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    const RgbParam kt = read_reflectance_param(props, "specular_transmission", Rgb(1.0f));
    return plain_or_textured(ks.varies() || kt.varies(), [eta, ks, kt](const Vec2* uv) {
        return make_bsdf_at<DielectricBsdf>(uv, eta, ks.at(uv), kt.at(uv));
    });
}

std::optional<BsdfSample> DielectricBsdf::sample(const Vec3& wo, float u_lobe, Vec2,
                                                 TransportMode mode) const {
    if (wo.z == 0 || !is_finite(wo)) return std::nullopt;
    const DielectricFresnel fresnel = fresnel_dielectric(wo.z, eta_);
    const float reflectance = fresnel.reflectance;

    BsdfSample s;
    s.delta = true;
    if (u_lobe < reflectance) {
        s.wi = reflect_z(wo);
        s.weight = specular_reflectance_;
        // The mirrored direction has the same cosine, hence the same selection probability.
        s.pdf_w = {reflectance, reflectance};
        s.lobe = kLobeDeltaReflection;
        return s;
    }
    s.wi = refract_z(wo, fresnel.cos_theta_t, fresnel.eta_ti);
    if (s.wi.z == 0) return std::nullopt;
    s.weight = specular_transmission_;
    // Radiance is compressed into the smaller solid angle of the denser side.
    if (mode == TransportMode::Radiance) s.weight *= fresnel.eta_ti * fresnel.eta_ti;
    s.pdf_w = {1.0f - reflectance, 1.0f - fresnel_dielectric(s.wi.z, eta_).reflectance};
    s.lobe = kLobeDeltaTransmission;
    s.eta = fresnel.eta_it;
    return s;
}

std::string DielectricBsdf::to_string() const {
    std::ostringstream out;
    out << "dielectric(eta " << eta_ << ", specular_reflectance " << specular_reflectance_
        << ", specular_transmission " << specular_transmission_ << ")";
    return out.str();
}

}  // namespace render
