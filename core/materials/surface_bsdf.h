#pragma once

// A BSDF placed at a surface point: converts world directions to the shading frame, rejects
// direction pairs whose shading and geometric classifications disagree (reflection vs.
// transmission: the source of light leaks with interpolated normals), and applies the
// shading-normal correction of adjoint transport (Veach 1997, section 5.3) in Importance mode.

#include <optional>

#include "core/materials/bsdf.h"
#include "core/math/frame.h"

namespace render {

// f and both directional (solid-angle) densities of one direction pair, from one frame
// conversion.
struct BsdfEvaluation {
    Rgb f;
    BsdfPdf pdf_w;
};

class SurfaceBsdf {
  public:
    SurfaceBsdf(const Bsdf& bsdf, const Frame& shading, const Vec3& geometric_normal,
                TransportMode mode)
        : bsdf_(bsdf),
          owner_(bsdf.built_for_hit() ? bsdf.shared_from_this() : nullptr),
          shading_(shading),
          ng_(geometric_normal),
          mode_(mode) {}

    // f(wo, wi) for world directions, corrected for shading normals (Importance mode).
    Rgb f(const Vec3& wo, const Vec3& wi) const;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const;
    // f and pdf_w together: connections and merges need both for the same pair.
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi) const;
    // Sampled world direction; the weight includes |cos| w.r.t. the shading normal and the
    // shading-normal correction.
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u) const;

    // |cos| between w and the shading normal.
    float abs_cos_shading(const Vec3& w) const { return std::abs(dot(w, shading_.n)); }
    const Vec3& geometric_normal() const { return ng_; }
    const Bsdf& bsdf() const { return bsdf_; }
    bool is_delta() const { return bsdf_.is_delta(); }

  private:
    // False if the pair is reflection for one normal and transmission for the other.
    bool consistent(const Vec3& wo, const Vec3& wi, const Vec3& wo_local,
                    const Vec3& wi_local) const;
    float shading_correction(const Vec3& wo, const Vec3& wi) const;

    const Bsdf& bsdf_;
    // Keeps a BSDF built for one hit (a textured material's) alive after the interaction that
    // owned it is gone, as stored light vertices need; null for the scene's own BSDFs.
    std::shared_ptr<const Bsdf> owner_;
    Frame shading_;
    Vec3 ng_;
    TransportMode mode_;
};

}  // namespace render
