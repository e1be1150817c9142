#include "core/lights/area_light.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/math/constants.h"
#include "core/math/frame.h"
#include "core/sampling/warp.h"
#include "core/shapes/triangle_mesh.h"

namespace render {

AreaLight::AreaLight(const Shape* shape, const RgbParam& radiance, bool importance_sampled)
    : AreaLight(shape, radiance.mean()) {
    if (!radiance.varies()) return;
    const auto* mesh = dynamic_cast<const TriangleMesh*>(shape);
    if (!shape || (!mesh && !shape->has_uv_lookup()))
        throw std::invalid_argument(
            "a textured radiance needs a shape whose uv can be found from a point (sphere, "
            "disk, rectangle, cube or a triangle mesh)");
    radiance_param_ = radiance;
    textured_ = true;
    // Also when uniform: the point lookup of meshes too large for TriangleMesh::uv_at.
    if (mesh && inv_area_ > 0) {
        mesh_emission_ = std::make_unique<TexturedMeshEmission>(*mesh, *radiance.texture);
        uniform_mesh_ = !importance_sampled;
    }
}

AreaLight::AreaLight(const Shape* shape, const Rgb& radiance)
    : shape_(shape), radiance_(radiance), area_(shape ? shape->surface_area() : 0.0f) {
    if (!(area_ > 0) || !std::isfinite(area_)) area_ = 0;
    inv_area_ = area_ > 0 ? 1.0f / area_ : 0.0f;
    // A denormal area would make 1 / area overflow.
    if (!std::isfinite(inv_area_)) area_ = inv_area_ = 0;
}

bool AreaLight::illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const {
    if (inv_area_ == 0 || radiance_.is_black()) return false;
    ShapeSample s = sample_point(u);
    if (!(s.pdf_area > 0) || !std::isfinite(s.pdf_area)) return false;
    Vec3 to_light = s.p - ref;
    float d2 = length_squared(to_light);
    if (!(d2 > 0) || !std::isfinite(d2)) return false;
    float d = std::sqrt(d2);
    Vec3 wi = to_light / d;
    float cos_light = dot(s.n, -wi);
    if (!(cos_light > 0)) return false;  // back side (one-sided) or grazing
    float pdf_w = s.pdf_area * d2 / cos_light;
    if (!std::isfinite(pdf_w)) return false;  // grazing to within float precision
    out.wi = wi;
    out.distance = d;
    out.radiance = radiance_at(s.uv);
    if (textured_ && out.radiance.is_black()) return false;
    out.pdf_direct_w = pdf_w;
    out.pdf_emission_w = s.pdf_area * cos_light * kInvPi;
    out.cos_at_light = cos_light;
    return true;
}

bool AreaLight::sample_position(Vec2 u, Vec3& position) const {
    if (inv_area_ == 0 || radiance_.is_black()) return false;
    const ShapeSample s = sample_point(u);
    position = s.p;
    return s.pdf_area > 0 && std::isfinite(s.pdf_area);
}

bool AreaLight::emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const {
    if (inv_area_ == 0 || radiance_.is_black()) return false;
    ShapeSample s = sample_point(u_position);
    if (!(s.pdf_area > 0) || !std::isfinite(s.pdf_area)) return false;
    Vec3 local = warp::square_to_cosine_hemisphere(u_direction);
    // Malley's method reaches cos = 0 only on the disk's rim; such a ray carries nothing.
    if (!(local.z > 0)) return false;
    out.origin = s.p;
    out.direction = normalize(Frame::from_normal(s.n).to_world(local));
    out.energy = radiance_at(s.uv) * local.z;
    if (textured_ && out.energy.is_black()) return false;
    out.pdf_emission_w = s.pdf_area * local.z * kInvPi;
    out.pdf_direct_a = s.pdf_area;
    out.cos_at_light = local.z;
    return true;
}

LightRadiance AreaLight::radiance(const Vec3& hit_point, const Vec3& hit_normal,
                                  const Vec3& ray_direction) const {
    const float cos_light = dot(hit_normal, -ray_direction);
    if (!(cos_light > 0) || inv_area_ == 0) return {};
    // Only the point is known: find the primitive and its parameters (a search where the
    // density or the texture's uv depends on them; nothing for uniform untextured shapes).
    unsigned prim_id = 0;
    Vec2 prim_uv;
    const bool on_shape = mesh_emission_ ? mesh_emission_->locate(hit_point, prim_id, prim_uv)
                                         : shape_->locate(hit_point, prim_id, prim_uv);
    if (!on_shape) return {};
    return radiance_of_hit(prim_id, prim_uv, hit_point, cos_light);
}

LightRadiance AreaLight::radiance_at(const SurfaceInteraction& hit,
                                     const Vec3& ray_direction) const {
    const float cos_light = dot(hit.geometric_normal, -ray_direction);
    if (!(cos_light > 0) || inv_area_ == 0) return {};
    return radiance_of_hit(hit.prim_id, hit.prim_uv, hit.p, cos_light);
}

LightRadiance AreaLight::radiance_of_hit(unsigned prim_id, Vec2 prim_uv, const Vec3& p,
                                         float cos_light) const {
    const float pdf_area = !mesh_emission_ ? shape_->pdf_area(prim_id, prim_uv)
                           : uniform_mesh_ ? inv_area_
                                           : mesh_emission_->pdf_at(prim_id, prim_uv);
    if (!(pdf_area > 0) || !std::isfinite(pdf_area)) return {};  // off the shape
    LightRadiance r;
    r.radiance = textured_ ? radiance_param_.texture->eval(shape_->uv_at_hit(prim_id, prim_uv, p))
                           : radiance_;
    r.pdf_direct_a = pdf_area;
    r.pdf_emission_w = pdf_area * cos_light * kInvPi;
    return r;
}

Rgb AreaLight::power() const {
    return radiance_ * (kPi * area_);
}

std::string AreaLight::to_string() const {
    std::ostringstream os;
    os << "AreaLight[radiance = " << radiance_;
    if (textured_) os << " (mean of " << radiance_param_.texture->to_string() << ")";
    os << ", area = " << area_
       << ", shape = " << (shape_ ? shape_->to_string() : std::string("none")) << "]";
    return os.str();
}

}  // namespace render
