#include "core/materials/conductor.h"

#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {

ConductorBsdf::ConductorBsdf(std::optional<ConductorIor> ior, const Rgb& specular_reflectance)
    : ior_(std::move(ior)), specular_reflectance_(specular_reflectance) {}

std::shared_ptr<const Bsdf> ConductorBsdf::create(const Properties& props) {
    const std::optional<ConductorIor> ior = read_conductor_ior(props);
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    return plain_or_textured(ks.varies(), [ior, ks](const Vec2* uv) {
        return make_bsdf_at<ConductorBsdf>(uv, ior, ks.at(uv));
    });
}

Rgb ConductorBsdf::reflectance(float cos_theta) const {
    if (!ior_) return specular_reflectance_;
    return specular_reflectance_ * fresnel_conductor(cos_theta, ior_->eta, ior_->k);
}

std::optional<BsdfSample> ConductorBsdf::sample(const Vec3& wo, float, Vec2, TransportMode) const {
    if (wo.z <= 0) return std::nullopt;
    BsdfSample s;
    s.wi = reflect_z(wo);
    s.weight = reflectance(wo.z);
    s.pdf_w = {1.0f, 1.0f};
    s.delta = true;
    s.lobe = kLobeDeltaReflection;
    return s;
}

std::string ConductorBsdf::to_string() const {
    std::ostringstream out;
    out << "conductor(";
    if (ior_)
        out << "eta " << ior_->eta << ", k " << ior_->k;
    else
        out << "no fresnel";
    out << ", specular_reflectance " << specular_reflectance_ << ")";
    return out.str();
}

}  // namespace render
