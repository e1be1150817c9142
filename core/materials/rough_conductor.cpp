#include "core/materials/rough_conductor.h"

#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {

RoughConductorBsdf::RoughConductorBsdf(const MicrofacetDistribution& distribution,
                                       std::optional<ConductorIor> ior,
                                       const Rgb& specular_reflectance)
    : distribution_(distribution),
      ior_(std::move(ior)),
      specular_reflectance_(specular_reflectance) {}

std::shared_ptr<const Bsdf> RoughConductorBsdf::create(const Properties& props) {
    const MicrofacetParams distribution = read_microfacet_params(props);
    const std::optional<ConductorIor> ior = read_conductor_ior(props);
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    return plain_or_textured(
        distribution.varies() || ks.varies(), [distribution, ior, ks](const Vec2* uv) {
            return make_bsdf_at<RoughConductorBsdf>(uv, distribution.at(uv), ior, ks.at(uv));
        });
}

Rgb RoughConductorBsdf::fresnel(float cos_theta) const {
    if (!ior_) return specular_reflectance_;
    return specular_reflectance_ * fresnel_conductor(cos_theta, ior_->eta, ior_->k);
}

Rgb RoughConductorBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0f);
    const Vec3 m = normalize(wo + wi);
    const float D = distribution_.D(m);
    if (D == 0) return Rgb(0.0f);
    const float G = distribution_.G(wo, wi, m);
    const Rgb result = fresnel(dot(wo, m)) * (D * G / (4.0f * wo.z * wi.z));
    return result.is_finite() ? result : Rgb(0.0f);
}

float RoughConductorBsdf::sample_density(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0.0f;
    const Vec3 m = normalize(wo + wi);
    const float wo_dot_m = dot(wo, m);
    if (wo_dot_m <= 0) return 0.0f;
    // Jacobian of the reflection map m -> wi: d omega_m / d omega_i = 1 / (4 wo.m).
    const float result = distribution_.pdf(wo, m) / (4.0f * wo_dot_m);
    return std::isfinite(result) ? result : 0.0f;
}

BsdfPdf RoughConductorBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    return {sample_density(wo, wi), sample_density(wi, wo)};
}

std::optional<BsdfSample> RoughConductorBsdf::sample(const Vec3& wo, float, Vec2 u,
                                                     TransportMode mode) const {
    if (wo.z <= 0) return std::nullopt;
    const Vec3 m = distribution_.sample(wo, u);
    const Vec3 wi = reflect(wo, m);
    if (wi.z <= 0) return std::nullopt;
    // Weight from the same f and pdf that evaluation reports, so MIS sees consistent values.
    BsdfSample s;
    s.wi = wi;
    s.pdf_w = pdf_w(wo, wi);
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = f(wo, wi, mode) * (wi.z / s.pdf_w.forward);
    if (!s.weight.is_finite()) return std::nullopt;
    s.lobe = kLobeGlossyReflection;
    return s;
}

std::string RoughConductorBsdf::to_string() const {
    std::ostringstream out;
    out << "roughconductor(" << render::to_string(distribution_.type()) << ", alpha "
        << distribution_.alpha_u();
    if (!distribution_.is_isotropic()) out << "/" << distribution_.alpha_v();
    if (ior_)
        out << ", eta " << ior_->eta << ", k " << ior_->k;
    else
        out << ", no fresnel";
    out << ", specular_reflectance " << specular_reflectance_ << ")";
    return out.str();
}

}  // namespace render
