#include "core/textures/checkerboard_texture.h"

#include <algorithm>
#include <cmath>

#include "core/textures/texture_factory.h"

namespace render {

CheckerboardTexture::CheckerboardTexture(std::shared_ptr<const Texture> color0,
                                         std::shared_ptr<const Texture> color1,
                                         const UvTransform& to_uv)
    : color0_(std::move(color0)), color1_(std::move(color1)), to_uv_(to_uv) {}

std::shared_ptr<const Texture> CheckerboardTexture::create(const Properties& props) {
    std::shared_ptr<const Texture> color0 = read_texture(props, "color0", Rgb(0.4f));
    std::shared_ptr<const Texture> color1 = read_texture(props, "color1", Rgb(0.2f));
    const UvTransform to_uv(props.get_transform("to_uv", Transform()));
    if (!to_uv.is_finite()) throw props.error("to_uv", "the transform is not finite");
    return std::make_shared<CheckerboardTexture>(std::move(color0), std::move(color1), to_uv);
}

Rgb CheckerboardTexture::eval(Vec2 uv) const {
    const Vec2 st = to_uv_.apply(uv);
    const bool s_high = st.x - std::floor(st.x) > 0.5f;
    const bool t_high = st.y - std::floor(st.y) > 0.5f;
    return s_high == t_high ? color0_->eval(uv) : color1_->eval(uv);
}

float CheckerboardTexture::min_value() const {
    return std::min(color0_->min_value(), color1_->min_value());
}

float CheckerboardTexture::max_value() const {
    return std::max(color0_->max_value(), color1_->max_value());
}

std::string CheckerboardTexture::to_string() const {
    return "checkerboard(" + color0_->to_string() + ", " + color1_->to_string() + ")";
}

}  // namespace render
