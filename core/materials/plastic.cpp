#include "core/materials/plastic.h"

#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

PlasticBsdf::PlasticBsdf(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance, float eta,
                         bool nonlinear)
    : diffuse_reflectance_(diffuse_reflectance),
      specular_reflectance_(specular_reflectance),
      eta_(eta),
      nonlinear_(nonlinear) {
    // Light inside the coating meets the interface from the dense side: relative IOR 1/eta.
    const PlasticBase base =
        plastic_base(diffuse_reflectance_, specular_reflectance_,
                     fresnel_diffuse_reflectance(1.0f / eta_), eta_, nonlinear_);
    diffuse_scaled_ = base.diffuse_scaled;
    specular_sampling_weight_ = base.specular_sampling_weight;
}

PlasticBase plastic_base(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance,
                         float internal_reflectance, float eta, bool nonlinear) {
    PlasticBase base;
    for (int c = 0; c < 3; ++c) {
        const float kd = diffuse_reflectance[c];
        const float escape = 1.0f - (nonlinear ? kd * internal_reflectance : internal_reflectance);
        base.diffuse_scaled[c] = escape > 0 ? kd / escape * kInvPi / (eta * eta) : 0.0f;
    }
    const float d = diffuse_reflectance.average(), s = specular_reflectance.average();
    base.specular_sampling_weight = d + s > 0 ? s / (d + s) : 0.5f;
    return base;
}

std::shared_ptr<const Bsdf> PlasticBsdf::create(const Properties& props) {
    const RgbParam kd = read_reflectance_param(props, "diffuse_reflectance", Rgb(0.5f));
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    const float eta = read_relative_ior(props, *lookup_dielectric_ior("polypropylene"));
    const bool nonlinear = props.get_bool("nonlinear", false);
    return plain_or_textured(kd.varies() || ks.varies(), [kd, ks, eta, nonlinear](const Vec2* uv) {
        return make_bsdf_at<PlasticBsdf>(uv, kd.at(uv), ks.at(uv), eta, nonlinear);
    });
}

float PlasticBsdf::specular_probability(float cos_theta) const {
    const float F = fresnel_dielectric(cos_theta, eta_).reflectance;
    const float specular = F * specular_sampling_weight_;
    const float diffuse = (1.0f - F) * (1.0f - specular_sampling_weight_);
    return specular + diffuse > 0 ? specular / (specular + diffuse) : 1.0f;
}

Rgb PlasticBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0f);
    const float t_o = 1.0f - fresnel_dielectric(wo.z, eta_).reflectance;
    const float t_i = 1.0f - fresnel_dielectric(wi.z, eta_).reflectance;
    return diffuse_scaled_ * (t_o * t_i);
}

float PlasticBsdf::sample_density(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0.0f;
    return (1.0f - specular_probability(wo.z)) * wi.z * kInvPi;
}

BsdfPdf PlasticBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    return {sample_density(wo, wi), sample_density(wi, wo)};
}

std::optional<BsdfSample> PlasticBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                              TransportMode mode) const {
    if (wo.z <= 0 || !is_finite(wo)) return std::nullopt;
    const float p_specular = specular_probability(wo.z);
    BsdfSample s;
    if (u_lobe < p_specular) {
        const float F = fresnel_dielectric(wo.z, eta_).reflectance;
        s.wi = reflect_z(wo);
        s.weight = specular_reflectance_ * (F / p_specular);
        s.pdf_w = {p_specular, p_specular};  // the mirror direction has the same cosine
        s.delta = true;
        s.lobe = kLobeDeltaReflection;
        return s;
    }
    s.wi = warp::square_to_cosine_hemisphere(u);
    if (s.wi.z <= 0) return std::nullopt;
    s.pdf_w = pdf_w(wo, s.wi);
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = f(wo, s.wi, mode) * (s.wi.z / s.pdf_w.forward);
    s.lobe = kLobeDiffuseReflection;
    return s;
}

std::string PlasticBsdf::to_string() const {
    std::ostringstream out;
    out << "plastic(diffuse_reflectance " << diffuse_reflectance_ << ", specular_reflectance "
        << specular_reflectance_ << ", eta " << eta_ << (nonlinear_ ? ", nonlinear" : "") << ")";
    return out.str();
}

}  // namespace render
