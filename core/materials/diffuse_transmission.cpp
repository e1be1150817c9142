#include "core/materials/diffuse_transmission.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

float max_component(const Rgb& c) {
    return std::max(c.r, std::max(c.g, c.b));
}

Rgb scaled_and_clamped(const Rgb& c, float scale) {
    const auto one = [scale](float v) { return std::clamp(v * scale, 0.0f, 1.0f); };
    return Rgb(one(c.r), one(c.g), one(c.b));
}

}  // namespace

DiffuseTransmissionBsdf::DiffuseTransmissionBsdf(const Rgb& reflectance, const Rgb& transmittance)
    : reflectance_(reflectance), transmittance_(transmittance) {
    const float pr = max_component(reflectance_), pt = max_component(transmittance_);
    p_reflect_ = pr + pt > 0 ? pr / (pr + pt) : 0.0f;
}

std::shared_ptr<const Bsdf> DiffuseTransmissionBsdf::create(const Properties& props) {
    const RgbParam reflectance = read_reflectance_param(props, "reflectance", Rgb(0.25f));
    const RgbParam transmittance = read_reflectance_param(props, "transmittance", Rgb(0.25f));
    const float scale = read_non_negative(props, "scale", 1.0f);
    return plain_or_textured(reflectance.varies() || transmittance.varies(),
                             [reflectance, transmittance, scale](const Vec2* uv) {
                                 return std::make_shared<DiffuseTransmissionBsdf>(
                                     scaled_and_clamped(reflectance.at(uv), scale),
                                     scaled_and_clamped(transmittance.at(uv), scale));
                             });
}

uint32_t DiffuseTransmissionBsdf::lobes() const {
    uint32_t l = kLobeNone;
    if (!reflectance_.is_black()) l |= kLobeDiffuseReflection;
    if (!transmittance_.is_black()) l |= kLobeDiffuseTransmission;
    return l;
}

float DiffuseTransmissionBsdf::side_density(bool same_side, float abs_cos) const {
    return (same_side ? p_reflect_ : 1.0f - p_reflect_) * abs_cos * kInvPi;
}

Rgb DiffuseTransmissionBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z == 0 || wi.z == 0) return Rgb(0.0f);
    return (wo.z * wi.z > 0 ? reflectance_ : transmittance_) * kInvPi;
}

BsdfPdf DiffuseTransmissionBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    if (wo.z == 0 || wi.z == 0) return {};
    const bool same = wo.z * wi.z > 0;
    return {side_density(same, std::abs(wi.z)), side_density(same, std::abs(wo.z))};
}

std::optional<BsdfSample> DiffuseTransmissionBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                                          TransportMode) const {
    if (wo.z == 0 || !(p_reflect_ > 0 || max_component(transmittance_) > 0)) return std::nullopt;
    const bool reflect = u_lobe < p_reflect_;
    Vec3 wi = warp::square_to_cosine_hemisphere(u);
    if (!(wi.z > 0)) return std::nullopt;
    // Reflection stays on wo's side, transmission goes to the other one.
    if ((wo.z < 0) == reflect) wi.z = -wi.z;
    BsdfSample s;
    s.wi = wi;
    const float p_lobe = reflect ? p_reflect_ : 1.0f - p_reflect_;
    // (C / pi) |cos| / (p_lobe |cos| / pi)
    s.weight = (reflect ? reflectance_ : transmittance_) / p_lobe;
    s.pdf_w = {side_density(reflect, std::abs(wi.z)), side_density(reflect, std::abs(wo.z))};
    s.lobe = reflect ? kLobeDiffuseReflection : kLobeDiffuseTransmission;
    return s;
}

std::string DiffuseTransmissionBsdf::to_string() const {
    std::ostringstream out;
    out << "diffusetransmission(reflectance " << reflectance_ << ", transmittance "
        << transmittance_ << ")";
    return out.str();
}

}  // namespace render
