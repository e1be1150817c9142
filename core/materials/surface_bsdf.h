#pragma once

// A BSDF placed at a surface point: converts world directions to the shading frame, rejects
// direction pairs whose shading and geometric classifications disagree (reflection vs.
// transmission: the source of light leaks with interpolated normals), and applies the
// shading-normal correction of adjoint transport (Veach 1997, section 5.3) in Importance mode.

#include <memory>
#include <optional>
#include <utility>

#include "core/materials/bsdf.h"
#include "core/math/frame.h"

namespace render {

class SurfaceBsdf {
  public:
    SurfaceBsdf(const Bsdf& bsdf, const Frame& shading, const Vec3& geometric_normal,
                TransportMode mode)
        : bsdf_(bsdf.built_for_hit()
                    ? bsdf.shared_from_this()
                    // The scene owns its BSDFs: an aliasing pointer that owns nothing.
                    : std::shared_ptr<const Bsdf>(std::shared_ptr<const Bsdf>(), &bsdf)),
          shading_(shading),
          ng_(geometric_normal),
          mode_(mode) {}

    // f(wo, wi) for world directions, corrected for shading normals (Importance mode).
    Rgb f(const Vec3& wo, const Vec3& wi) const;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const;
    // f and pdf_w together, from one frame conversion and one call of the model (which
    // returns exactly what its f and pdf_w do): connections and merges need both.
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi) const;
    // Sampled world direction; the weight includes |cos| w.r.t. the shading normal and the
    // shading-normal correction.
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u) const;

    // |cos| between w and the shading normal.
    float abs_cos_shading(const Vec3& w) const { return std::abs(dot(w, shading_.n)); }
    const Vec3& geometric_normal() const { return ng_; }
    const Bsdf& bsdf() const { return *bsdf_; }
    bool is_delta() const { return bsdf_->is_delta(); }

  private:
    friend class OptionalSurfaceBsdf;
    SurfaceBsdf() = default;  // empty: only OptionalSurfaceBsdf's disengaged state

    // False if the pair is reflection for one normal and transmission for the other.
    bool consistent(const Vec3& wo, const Vec3& wi, const Vec3& wo_local,
                    const Vec3& wi_local) const;
    float shading_correction(const Vec3& wo, const Vec3& wi) const;

    // The BSDF; for one built for a single hit (a textured material's) it also keeps it alive
    // after the interaction that owned it is gone, as stored light vertices need. The scene's
    // own BSDFs are not owned (no reference count is touched). One pointer where a reference
    // and an owner used to be: 8 bytes less per stored light vertex.
    std::shared_ptr<const Bsdf> bsdf_;
    Frame shading_;
    Vec3 ng_;
    TransportMode mode_ = TransportMode::Radiance;
};

// std::optional<SurfaceBsdf> without optional's separate engaged flag (8 bytes with padding):
// empty is a null BSDF pointer. Stored light vertices hold one each (bidirectional/subpath.h), so a
// smaller record is a smaller iteration. The subset of std::optional's interface they use.
class OptionalSurfaceBsdf {
  public:
    OptionalSurfaceBsdf() = default;
    OptionalSurfaceBsdf(std::nullopt_t) {}
    OptionalSurfaceBsdf(const SurfaceBsdf& b) : value_(b) {}

    template <class... Args>
    SurfaceBsdf& emplace(Args&&... args) {
        value_ = SurfaceBsdf(std::forward<Args>(args)...);
        return value_;
    }
    void reset() { value_ = SurfaceBsdf(); }

    bool has_value() const { return value_.bsdf_ != nullptr; }
    explicit operator bool() const { return has_value(); }
    const SurfaceBsdf& operator*() const { return value_; }
    const SurfaceBsdf* operator->() const { return &value_; }
    SurfaceBsdf& operator*() { return value_; }
    SurfaceBsdf* operator->() { return &value_; }
    operator std::optional<SurfaceBsdf>() const {
        return has_value() ? std::optional<SurfaceBsdf>(value_) : std::nullopt;
    }

  private:
    [[no_unique_address]] SurfaceBsdf value_;  // its tail padding is free for the owner
};

}  // namespace render
