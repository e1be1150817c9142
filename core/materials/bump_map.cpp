#include "core/materials/bump_map.h"

#include <cmath>

#include "core/base/error.h"
#include "core/materials/normal_map.h"

namespace render {

Frame bump_mapped_frame(Vec2 grad, const Frame& shading, const Vec3& dpdu, const Vec3& dpdv) {
    // A flat height field leaves the frame exactly as it is (bit-identical images).
    if (grad.x == 0 && grad.y == 0) return shading;
    if (!std::isfinite(grad.x) || !std::isfinite(grad.y)) return shading;
    const Vec3& n = shading.n;
    const Vec3 su = dpdu - n * dot(n, dpdu), sv = dpdv - n * dot(n, dpdv);
    const Vec3 base = cross(su, sv);
    if (!(length(base) > 0) || !std::isfinite(length(base))) return shading;
    Vec3 m = cross(su + n * grad.x, sv + n * grad.y);
    const float len = length(m);
    if (!(len > 0) || !std::isfinite(len)) return shading;
    m = m / len;
    // The side of the shading normal (uv may run either way round the normal).
    if (dot(base, n) < 0) m = -m;
    return frame_with_tangent(m, dpdu);
}

BumpMapBsdf::BumpMapBsdf(std::shared_ptr<const Bsdf> nested, std::shared_ptr<const Texture> height,
                         float scale)
    : ShadingFrameBsdf(std::move(nested)), height_(std::move(height)), scale_(scale) {}

std::shared_ptr<const Bsdf> BumpMapBsdf::create(const Properties& props) {
    const std::shared_ptr<const Bsdf>& nested = the_nested_bsdf(props, "bumpmap");
    const float scale = props.get_float("scale", 1.0f);
    if (!std::isfinite(scale)) throw props.error("scale", "must be finite");
    // Mitsuba takes its one texture whatever its name.
    std::shared_ptr<const Texture> height;
    std::string name;
    for (const auto& [param, where] : props.unused()) {
        std::shared_ptr<const Texture> t = props.get_texture(param);
        if (!t) continue;
        if (height)
            throw props.error(
                param, "bsdf \"bumpmap\" takes one texture, \"" + name + "\" was given already");
        height = std::move(t);
        name = param;
    }
    if (!height) throw SceneError(props.where(), "bsdf \"bumpmap\" needs a height <texture>");
    if (!std::isfinite(height->min_value()) || !std::isfinite(height->max_value()))
        throw props.error(name, "the height texture must be finite");
    return std::make_shared<BumpMapBsdf>(nested, std::move(height), scale);
}

Vec2 BumpMapBsdf::gradient(Vec2 uv) const {
    const float du =
        height_->eval_1(Vec2(uv.x + kStep, uv.y)) - height_->eval_1(Vec2(uv.x - kStep, uv.y));
    const float dv =
        height_->eval_1(Vec2(uv.x, uv.y + kStep)) - height_->eval_1(Vec2(uv.x, uv.y - kStep));
    const float k = scale_ / (2 * kStep);
    return Vec2(du * k, dv * k);
}

Frame BumpMapBsdf::shading_frame(const SurfaceInteraction& si) const {
    return bump_mapped_frame(gradient(si.uv), si.shading, si.dpdu, si.dpdv);
}

std::string BumpMapBsdf::to_string() const {
    return "bumpmap(" + height_->to_string() + ", scale " + std::to_string(scale_) + ", " +
           nested_->to_string() + ")";
}

}  // namespace render
