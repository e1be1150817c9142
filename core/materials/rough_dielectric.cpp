#include "core/materials/rough_dielectric.h"

#include <cmath>
#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {

RoughDielectricBsdf::RoughDielectricBsdf(const MicrofacetDistribution& distribution, float eta,
                                         const Rgb& specular_reflectance,
                                         const Rgb& specular_transmission)
    : distribution_(distribution),
      eta_(eta),
      specular_reflectance_(specular_reflectance),
      specular_transmission_(specular_transmission) {}

std::shared_ptr<const Bsdf> RoughDielectricBsdf::create(const Properties& props) {
    const MicrofacetParams distribution = read_microfacet_params(props);
    const float eta = read_relative_ior(props, *lookup_dielectric_ior("bk7"));
    if (eta == 1.0f)
        throw props.error("int_ior",
                          "equals ext_ior: a rough index-matched interface has no half vector");
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    const RgbParam kt = read_reflectance_param(props, "specular_transmission", Rgb(1.0f));
    return plain_or_textured(distribution.varies() || ks.varies() || kt.varies(),
                             [distribution, eta, ks, kt](const Vec2* uv) {
                                 return make_bsdf_at<RoughDielectricBsdf>(
                                     uv, distribution.at(uv), eta, ks.at(uv), kt.at(uv));
                             });
}

std::optional<RoughDielectricBsdf::HalfVector> RoughDielectricBsdf::half_vector(
    const Vec3& wo, const Vec3& wi) const {
    if (wo.z == 0 || wi.z == 0) return std::nullopt;
    const bool reflection = wo.z * wi.z > 0;
    const float etap = reflection ? 1.0f : (wo.z > 0 ? eta_ : 1.0f / eta_);
    Vec3 m = wi * etap + wo;
    const float len2 = length_squared(m);
    if (!(len2 > 0)) return std::nullopt;
    m = m / std::sqrt(len2);
    if (m.z < 0) m = -m;
    // Each direction must see the front of the micro-facet from its own side.
    if (!(m.z > 0) || dot(wo, m) * wo.z <= 0 || dot(wi, m) * wi.z <= 0) return std::nullopt;
    return HalfVector{m, etap};
}

Rgb RoughDielectricBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    const std::optional<HalfVector> h = half_vector(wo, wi);
    if (!h) return Rgb(0.0f);
    const float D = distribution_.D(h->m);
    if (D == 0) return Rgb(0.0f);
    const float G = distribution_.G(wo, wi, h->m);
    const float wo_m = dot(wo, h->m), wi_m = dot(wi, h->m);
    const float F = fresnel_dielectric(wo_m, eta_).reflectance;
    Rgb result;
    if (wo.z * wi.z > 0) {
        result = specular_reflectance_ * (F * D * G / (4.0f * std::abs(wo.z * wi.z)));
    } else {
        const float denom = (wi_m + wo_m / h->etap) * (wi_m + wo_m / h->etap);
        float value = (1.0f - F) * D * G * std::abs(wi_m * wo_m / (wo.z * wi.z * denom));
        if (mode == TransportMode::Radiance) value /= h->etap * h->etap;
        result = specular_transmission_ * value;
    }
    return result.is_finite() ? result : Rgb(0.0f);
}

float RoughDielectricBsdf::sample_density(const Vec3& wo, const Vec3& wi) const {
    const std::optional<HalfVector> h = half_vector(wo, wi);
    if (!h) return 0.0f;
    const Vec3 wo_up = wo.z > 0 ? wo : -wo;
    const float pdf_m = distribution_.pdf(wo_up, h->m);
    const float wo_m = dot(wo, h->m), wi_m = dot(wi, h->m);
    const float F = fresnel_dielectric(wo_m, eta_).reflectance;
    float result;
    if (wo.z * wi.z > 0) {
        // Reflection: d omega_m / d omega_i = 1 / (4 |wo.m|).
        result = F * pdf_m / (4.0f * std::abs(wo_m));
    } else {
        // Refraction: d omega_m / d omega_i = |wi.m| / (wi.m + wo.m / etap)^2.
        const float denom = (wi_m + wo_m / h->etap) * (wi_m + wo_m / h->etap);
        result = (1.0f - F) * pdf_m * std::abs(wi_m) / denom;
    }
    return std::isfinite(result) ? result : 0.0f;
}

BsdfPdf RoughDielectricBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    return {sample_density(wo, wi), sample_density(wi, wo)};
}

std::optional<BsdfSample> RoughDielectricBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                                      TransportMode mode) const {
    if (wo.z == 0 || !is_finite(wo)) return std::nullopt;
    const Vec3 m = distribution_.sample(wo.z > 0 ? wo : -wo, u);
    const float wo_m = dot(wo, m);
    if (wo_m * wo.z <= 0) return std::nullopt;  // back-facing normal (non-visible sampling)
    const DielectricFresnel fresnel = fresnel_dielectric(wo_m, eta_);

    BsdfSample s;
    if (u_lobe < fresnel.reflectance) {
        s.wi = normalize(reflect(wo, m));
        if (s.wi.z * wo.z <= 0) return std::nullopt;
        s.lobe = kLobeGlossyReflection;
    } else {
        s.wi = normalize(refract(wo, m, fresnel.cos_theta_t, fresnel.eta_ti));
        if (s.wi.z * wo.z >= 0) return std::nullopt;
        s.lobe = kLobeGlossyTransmission;
        s.eta = fresnel.eta_it;
    }
    // Weight from the same f and pdf that evaluation reports, so MIS sees consistent values.
    s.pdf_w = pdf_w(wo, s.wi);
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = f(wo, s.wi, mode) * (std::abs(s.wi.z) / s.pdf_w.forward);
    if (!s.weight.is_finite()) return std::nullopt;
    return s;
}

std::string RoughDielectricBsdf::to_string() const {
    std::ostringstream out;
    out << "roughdielectric(" << render::to_string(distribution_.type()) << ", alpha "
        << distribution_.alpha_u();
    if (!distribution_.is_isotropic()) out << "/" << distribution_.alpha_v();
    out << ", eta " << eta_ << ", specular_reflectance " << specular_reflectance_
        << ", specular_transmission " << specular_transmission_ << ")";
    return out.str();
}

}  // namespace render
