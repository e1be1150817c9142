#include "core/materials/surface_bsdf.h"

#include <cmath>

namespace render {

bool SurfaceBsdf::consistent(const Vec3& wo, const Vec3& wi, const Vec3& wo_local,
                             const Vec3& wi_local) const {
    float geometric = dot(wo, ng_) * dot(wi, ng_);
    float shading = wo_local.z * wi_local.z;
    if (geometric == 0 || shading == 0) return false;
    return (geometric > 0) == (shading > 0);
}

float SurfaceBsdf::shading_correction(const Vec3& wo, const Vec3& wi) const {
    if (mode_ == TransportMode::Radiance) return 1.0f;
    // Importance transport: |wo.ns| |wi.ng| / (|wo.ng| |wi.ns|) keeps the adjoint BSDF
    // consistent with the radiance BSDF when shading and geometric normals differ.
    float num = std::abs(dot(wo, shading_.n) * dot(wi, ng_));
    float den = std::abs(dot(wo, ng_) * dot(wi, shading_.n));
    return den > 0 ? num / den : 0.0f;
}

Rgb SurfaceBsdf::f(const Vec3& wo, const Vec3& wi) const {
    Vec3 wo_local = shading_.to_local(wo), wi_local = shading_.to_local(wi);
    if (!consistent(wo, wi, wo_local, wi_local)) return Rgb(0.0f);
    return bsdf_->f(wo_local, wi_local, mode_) * shading_correction(wo, wi);
}

BsdfPdf SurfaceBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    Vec3 wo_local = shading_.to_local(wo), wi_local = shading_.to_local(wi);
    if (!consistent(wo, wi, wo_local, wi_local)) return {};
    return bsdf_->pdf_w(wo_local, wi_local);
}

BsdfEvaluation SurfaceBsdf::evaluate(const Vec3& wo, const Vec3& wi) const {
    const Vec3 wo_local = shading_.to_local(wo), wi_local = shading_.to_local(wi);
    if (!consistent(wo, wi, wo_local, wi_local)) return {};
    BsdfEvaluation e = bsdf_->evaluate(wo_local, wi_local, mode_);
    if (mode_ == TransportMode::Importance) e.f = e.f * shading_correction(wo, wi);
    return e;
}

std::optional<BsdfSample> SurfaceBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u) const {
    Vec3 wo_local = shading_.to_local(wo);
    if (wo_local.z == 0) return std::nullopt;
    std::optional<BsdfSample> s = bsdf_->sample(wo_local, u_lobe, u, mode_);
    if (!s) return std::nullopt;
    Vec3 wi_local = s->wi;
    s->wi = shading_.to_world(wi_local);
    if (!consistent(wo, s->wi, wo_local, wi_local)) return std::nullopt;
    s->weight *= shading_correction(wo, s->wi);
    if (!s->weight.is_finite()) return std::nullopt;
    return s;
}

}  // namespace render
