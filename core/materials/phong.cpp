#include "core/materials/phong.h"

#include <cmath>
#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/math/frame.h"
#include "core/sampling/warp.h"

namespace render {

PhongBsdf::PhongBsdf(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance,
                     float exponent)
    : diffuse_reflectance_(diffuse_reflectance),
      specular_reflectance_(specular_reflectance),
      exponent_(exponent) {
    const float d = diffuse_reflectance_.average(), s = specular_reflectance_.average();
    specular_sampling_weight_ = d + s > 0 ? s / (d + s) : 0.0f;
}

std::shared_ptr<const Bsdf> PhongBsdf::create(const Properties& props) {
    const RgbParam kd = read_reflectance_param(props, "diffuse_reflectance", Rgb(0.5f));
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(0.2f));
    const float exponent = read_non_negative(props, "exponent", 30.0f);
    return plain_or_textured(kd.varies() || ks.varies(), [kd, ks, exponent](const Vec2* uv) {
        return make_bsdf_at<PhongBsdf>(uv, kd.at(uv), ks.at(uv), exponent);
    });
}

Rgb PhongBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0f);
    Rgb result = diffuse_reflectance_ * kInvPi;
    const float cos_alpha = dot(reflect_z(wo), wi);
    if (cos_alpha > 0)
        result += specular_reflectance_ *
                  ((exponent_ + 2.0f) * kInv2Pi * std::pow(std::min(cos_alpha, 1.0f), exponent_));
    return result;
}

BsdfPdf PhongBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    // p(wi | wo) of sample(), the mixture of both lobes, and p(wo | wi), with one power of the
    // lobe's cosine: dot(reflect_z(wi), wo) is dot(reflect_z(wo), wi) bit for bit (the same
    // products, negated alike, summed in the same order), so the two share it.
    if (wo.z <= 0 || wi.z <= 0) return {};
    const float cos_alpha = std::min(dot(reflect_z(wo), wi), 1.0f);
    const float specular =
        cos_alpha > 0 ? (exponent_ + 1.0f) * kInv2Pi * std::pow(cos_alpha, exponent_) : 0.0f;
    return {
        specular_sampling_weight_ * specular + (1.0f - specular_sampling_weight_) * (wi.z * kInvPi),
        specular_sampling_weight_ * specular +
            (1.0f - specular_sampling_weight_) * (wo.z * kInvPi)};
}

BsdfEvaluation PhongBsdf::evaluate(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return {};
    // f's and pdf_w's expressions, term for term, sharing the power (see pdf_w: the lobe's
    // cosine is the same for both directions, and min(c, 1) > 0 exactly when c > 0).
    const float cos_alpha = dot(reflect_z(wo), wi);
    const float power = cos_alpha > 0 ? std::pow(std::min(cos_alpha, 1.0f), exponent_) : 0.0f;
    Rgb f = diffuse_reflectance_ * kInvPi;
    float specular = 0.0f;
    if (cos_alpha > 0) {
        f += specular_reflectance_ * ((exponent_ + 2.0f) * kInv2Pi * power);
        specular = (exponent_ + 1.0f) * kInv2Pi * power;
    }
    return {f,
            {specular_sampling_weight_ * specular +
                 (1.0f - specular_sampling_weight_) * (wi.z * kInvPi),
             specular_sampling_weight_ * specular +
                 (1.0f - specular_sampling_weight_) * (wo.z * kInvPi)}};
}

std::optional<BsdfSample> PhongBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                            TransportMode mode) const {
    if (wo.z <= 0 || !is_finite(wo)) return std::nullopt;
    if (diffuse_reflectance_.is_black() && specular_reflectance_.is_black()) return std::nullopt;
    BsdfSample s;
    if (u_lobe < specular_sampling_weight_) {
        const Vec3 lobe_local = warp::square_to_phong_lobe(u, exponent_);
        s.wi = normalize(Frame::from_normal(reflect_z(wo)).to_world(lobe_local));
        s.lobe = kLobeGlossyReflection;
    } else {
        s.wi = warp::square_to_cosine_hemisphere(u);
        s.lobe = kLobeDiffuseReflection;
    }
    if (s.wi.z <= 0) return std::nullopt;  // the specular lobe dipped below the surface
    const BsdfEvaluation e = evaluate(wo, s.wi, mode);
    s.pdf_w = e.pdf_w;
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = e.f * (s.wi.z / s.pdf_w.forward);
    if (!s.weight.is_finite()) return std::nullopt;
    return s;
}

std::string PhongBsdf::to_string() const {
    std::ostringstream out;
    out << "phong(diffuse_reflectance " << diffuse_reflectance_ << ", specular_reflectance "
        << specular_reflectance_ << ", exponent " << exponent_ << ")";
    return out.str();
}

}  // namespace render
