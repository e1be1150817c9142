#include "core/materials/twosided.h"

#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"

namespace render {
namespace {

Vec3 flip_z(const Vec3& w) {
    return {w.x, w.y, -w.z};
}

}  // namespace

TwoSidedBsdf::TwoSidedBsdf(std::shared_ptr<const Bsdf> front, std::shared_ptr<const Bsdf> back)
    : front_(std::move(front)), back_(back ? std::move(back) : front_) {}

std::shared_ptr<const Bsdf> TwoSidedBsdf::create(const Properties& props) {
    const size_t n = props.nested_bsdfs.size();
    if (n == 0 || n > 2)
        throw SceneError(props.where(),
                         "bsdf \"twosided\" needs one nested bsdf (or two: front "
                         "and back), got " +
                             std::to_string(n));
    for (const auto& child : props.nested_bsdfs)
        if (child->lobes() & kLobeTransmission)
            throw SceneError(props.where(), "bsdf \"twosided\" cannot wrap the transmissive " +
                                                child->to_string());
    std::shared_ptr<const Bsdf> front = props.nested_bsdfs[0];
    std::shared_ptr<const Bsdf> back = n == 2 ? props.nested_bsdfs[1] : nullptr;
    const bool varies = front->varies() || (back && back->varies());
    // A textured side is resolved at the hit like any textured material; the mean side of a
    // textured child is its typical BSDF (the child itself answers as that).
    return plain_or_textured(varies, [front, back](const Vec2* uv) {
        auto side = [uv](const std::shared_ptr<const Bsdf>& b) {
            return b && uv && b->varies() ? b->at(*uv) : b;
        };
        return make_bsdf_at<TwoSidedBsdf>(uv, side(front), side(back));
    });
}

Rgb TwoSidedBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    if (wo.z > 0) return front_->f(wo, wi, mode);
    if (wo.z < 0) return back_->f(flip_z(wo), flip_z(wi), mode);
    return Rgb(0.0f);
}

BsdfPdf TwoSidedBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    if (wo.z > 0) return front_->pdf_w(wo, wi);
    if (wo.z < 0) return back_->pdf_w(flip_z(wo), flip_z(wi));
    return {};
}

BsdfEvaluation TwoSidedBsdf::evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    if (wo.z > 0) return front_->evaluate(wo, wi, mode);
    if (wo.z < 0) return back_->evaluate(flip_z(wo), flip_z(wi), mode);
    return {};
}

std::optional<BsdfSample> TwoSidedBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                               TransportMode mode) const {
    if (wo.z > 0) return front_->sample(wo, u_lobe, u, mode);
    if (wo.z == 0) return std::nullopt;
    std::optional<BsdfSample> s = back_->sample(flip_z(wo), u_lobe, u, mode);
    if (s) s->wi = flip_z(s->wi);
    return s;
}

std::string TwoSidedBsdf::to_string() const {
    if (front_ == back_) return "twosided(" + front_->to_string() + ")";
    return "twosided(front " + front_->to_string() + ", back " + back_->to_string() + ")";
}

}  // namespace render
