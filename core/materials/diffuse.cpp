#include "core/materials/diffuse.h"

#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

std::shared_ptr<const Bsdf> DiffuseBsdf::create(const Properties& props) {
    const RgbParam reflectance = read_reflectance_param(props, "reflectance", Rgb(0.5f));
    return plain_or_textured(reflectance.varies(), [reflectance](const Vec2* uv) {
        return make_bsdf_at<DiffuseBsdf>(uv, reflectance.at(uv));
    });
}

Rgb DiffuseBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0f);
    return reflectance_ * kInvPi;
}

BsdfPdf DiffuseBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return {};
    return {wi.z * kInvPi, wo.z * kInvPi};
}

BsdfEvaluation DiffuseBsdf::evaluate(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return {};
    return {reflectance_ * kInvPi, {wi.z * kInvPi, wo.z * kInvPi}};
}

std::optional<BsdfSample> DiffuseBsdf::sample(const Vec3& wo, float, Vec2 u, TransportMode) const {
    if (wo.z <= 0) return std::nullopt;
    const Vec3 wi = warp::square_to_cosine_hemisphere(u);
    if (wi.z <= 0) return std::nullopt;
    BsdfSample s;
    s.wi = wi;
    s.weight = reflectance_;  // (R / pi) cos / (cos / pi)
    s.pdf_w = {wi.z * kInvPi, wo.z * kInvPi};
    s.lobe = kLobeDiffuseReflection;
    return s;
}

std::string DiffuseBsdf::to_string() const {
    std::ostringstream out;
    out << "diffuse(reflectance " << reflectance_ << ")";
    return out.str();
}

}  // namespace render
