#include "core/materials/normal_map.h"

#include <cmath>

#include "core/base/error.h"

namespace render {
namespace {

// A unit tangent along `dpdu` orthogonal to unit `n`, or none when dp/du (nearly) vanishes
// there.
bool tangent_along(const Vec3& dpdu, const Vec3& n, Vec3& s) {
    const Vec3 v = dpdu - n * dot(n, dpdu);
    const float len = length(v);
    if (!(len > 1e-6f * length(dpdu)) || !std::isfinite(len)) return false;
    s = v / len;
    return true;
}

}  // namespace

Frame frame_with_tangent(const Vec3& n, const Vec3& dpdu) {
    Vec3 s;
    if (!tangent_along(dpdu, n, s)) return Frame::from_normal(n);
    return Frame(s, cross(n, s), n);
}

Frame normal_mapped_frame(const Vec3& local, const Frame& shading, const Vec3& dpdu) {
    // A flat texel (the map's (0.5, 0.5, 1)) leaves the frame exactly as it is.
    if (local.x == 0 && local.y == 0 && local.z > 0) return shading;
    const Frame tangent = frame_with_tangent(shading.n, dpdu);
    const Vec3 n = tangent.to_world(local);
    const float len = length(n);
    if (!(len > 0) || !std::isfinite(len)) return shading;  // a black texel: no tilt
    return frame_with_tangent(n / len, dpdu);
}

NormalMapBsdf::NormalMapBsdf(std::shared_ptr<const Bsdf> nested, std::shared_ptr<const Texture> map,
                             Rgb constant)
    : ShadingFrameBsdf(std::move(nested)), map_(std::move(map)), constant_(constant) {}

std::shared_ptr<const Bsdf> NormalMapBsdf::create(const Properties& props) {
    const std::shared_ptr<const Bsdf>& nested = the_nested_bsdf(props, "normalmap");
    std::shared_ptr<const Texture> map = props.get_texture("normalmap");
    Rgb constant(0.5f, 0.5f, 1.0f);
    if (map) {
        if (!std::isfinite(map->min_value()) || !std::isfinite(map->max_value()))
            throw props.error("normalmap", "the texture must be finite");
    } else {
        if (!props.has("normalmap"))
            throw props.error("normalmap", "bsdf \"normalmap\" needs a \"normalmap\" texture");
        constant = props.get_rgb("normalmap");
        if (!std::isfinite(constant.r) || !std::isfinite(constant.g) || !std::isfinite(constant.b))
            throw props.error("normalmap", "must be finite");
    }
    return std::make_shared<NormalMapBsdf>(nested, std::move(map), constant);
}

Frame NormalMapBsdf::shading_frame(const SurfaceInteraction& si) const {
    const Rgb c = map_ ? map_->eval(si.uv) : constant_;
    return normal_mapped_frame(Vec3(2 * c.r - 1, 2 * c.g - 1, 2 * c.b - 1), si.shading, si.dpdu);
}

std::string NormalMapBsdf::to_string() const {
    return "normalmap(" + (map_ ? map_->to_string() : "constant") + ", " + nested_->to_string() +
           ")";
}

}  // namespace render
