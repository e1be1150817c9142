#include "core/materials/blend.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/null_bsdf.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"

namespace render {
namespace {

std::string format(float value) {
    std::ostringstream out;
    out << value;
    return out.str();
}

// `name` as a float or a texture's single value (luminance), the constant checked to be
// finite. Textures and constants are clamped to [0, 1] where they are used, as Mitsuba does.
FloatParam read_weight(const Properties& props, const std::string& name) {
    if (std::shared_ptr<const Texture> texture = props.get_texture(name)) {
        const float lo = texture->min_value(), hi = texture->max_value();
        if (!std::isfinite(lo) || !std::isfinite(hi))
            throw props.error(name, "the texture must be finite (" + texture->to_string() + ")");
        return FloatParam{0.0f, texture};
    }
    const float value = props.get_float(name, 0.5f);
    if (!std::isfinite(value))
        throw props.error(name, "must be finite (got " + format(value) + ")");
    return FloatParam{value, nullptr};
}

float clamp01(float w) {
    return std::clamp(w, 0.0f, 1.0f);
}

std::shared_ptr<const Bsdf> resolve(const std::shared_ptr<const Bsdf>& b, const Vec2* uv) {
    return uv && b->varies() ? b->at(*uv) : b;
}

std::shared_ptr<const Bsdf> make_blend(std::shared_ptr<const Bsdf> first,
                                       std::shared_ptr<const Bsdf> second, const FloatParam& w,
                                       bool mask) {
    const bool varies = w.varies() || first->varies() || second->varies();
    return plain_or_textured(varies, [first, second, w, mask](const Vec2* uv) {
        return make_bsdf_at<BlendBsdf>(uv, resolve(first, uv), resolve(second, uv),
                                       clamp01(w.at(uv)), mask);
    });
}

}  // namespace

BlendBsdf::BlendBsdf(std::shared_ptr<const Bsdf> first, std::shared_ptr<const Bsdf> second,
                     float weight, bool mask)
    : first_(std::move(first)),
      second_(std::move(second)),
      weight_(clamp01(weight)),
      mask_(mask),
      lobes_(first_->lobes() | second_->lobes()) {}

std::shared_ptr<const Bsdf> BlendBsdf::create(const Properties& props) {
    if (props.nested_bsdfs.size() != 2)
        throw SceneError(props.where(), "bsdf \"blendbsdf\" needs two nested bsdfs, got " +
                                            std::to_string(props.nested_bsdfs.size()));
    return make_blend(props.nested_bsdfs[0], props.nested_bsdfs[1], read_weight(props, "weight"),
                      false);
}

std::shared_ptr<const Bsdf> BlendBsdf::create_mask(const Properties& props) {
    if (props.nested_bsdfs.size() != 1)
        throw SceneError(props.where(), "bsdf \"mask\" needs one nested bsdf, got " +
                                            std::to_string(props.nested_bsdfs.size()));
    return make_blend(std::make_shared<NullBsdf>(), props.nested_bsdfs[0],
                      read_weight(props, "opacity"), true);
}

Rgb BlendBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    Rgb result(0.0f);
    if (weight_ < 1) result += first_->f(wo, wi, mode) * (1 - weight_);
    if (weight_ > 0) result += second_->f(wo, wi, mode) * weight_;
    return result;
}

BsdfPdf BlendBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    BsdfPdf result;
    if (weight_ < 1) {
        const BsdfPdf p = first_->pdf_w(wo, wi);
        result.forward += (1 - weight_) * p.forward;
        result.reverse += (1 - weight_) * p.reverse;
    }
    if (weight_ > 0) {
        const BsdfPdf p = second_->pdf_w(wo, wi);
        result.forward += weight_ * p.forward;
        result.reverse += weight_ * p.reverse;
    }
    return result;
}

std::optional<BsdfSample> BlendBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                            TransportMode mode) const {
    // The second BSDF for u_lobe < w, the first otherwise; u_lobe rescaled to [0, 1).
    const bool second = u_lobe < weight_;
    const float choice = second ? weight_ : 1 - weight_;
    if (!(choice > 0)) return std::nullopt;
    const float u_child =
        std::min(second ? u_lobe / weight_ : (u_lobe - weight_) / (1 - weight_), kOneMinusEpsilon);
    std::optional<BsdfSample> s = (second ? second_ : first_)->sample(wo, u_child, u, mode);
    if (!s) return std::nullopt;
    if (s->delta) {
        // A delta lobe belongs to one child: its weight is the child's (the selection
        // probability cancels), its discrete probabilities include the selection.
        s->pdf_w.forward *= choice;
        s->pdf_w.reverse *= choice;
        return s;
    }
    s->pdf_w = pdf_w(wo, s->wi);
    if (!(s->pdf_w.forward > 0)) return std::nullopt;
    s->weight = f(wo, s->wi, mode) * (std::abs(s->wi.z) / s->pdf_w.forward);
    if (!s->weight.is_finite()) return std::nullopt;
    return s;
}

std::string BlendBsdf::to_string() const {
    std::ostringstream out;
    if (mask_)
        out << "mask(opacity " << weight_ << ", " << second_->to_string() << ")";
    else
        out << "blendbsdf(weight " << weight_ << ", " << first_->to_string() << ", "
            << second_->to_string() << ")";
    return out.str();
}

}  // namespace render
