#pragma once

// The BSDF interface. All directions are unit vectors in the local *shading* frame (z = shading
// normal) and point away from the surface: `wo` toward where the path came from, `wi` toward
// where it continues. Which of the two carries light depends on the transport mode:
//   Radiance   (eye paths):   light flows wi -> wo.
//   Importance (light paths): light flows wo -> wi (the path was traced from the light).
// Conversions to world space, geometric-normal checks and the shading-normal correction of
// adjoint transport live in SurfaceBsdf (surface_bsdf.h), not in each model.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "core/base/interaction.h"
#include "core/math/frame.h"
#include "core/math/vec.h"

namespace render {

enum class TransportMode { Radiance, Importance };

// Lobe kinds a BSDF may contain (bit flags).
enum BsdfLobe : uint32_t {
    kLobeNone = 0,
    kLobeDiffuseReflection = 1u << 0,
    kLobeGlossyReflection = 1u << 1,
    kLobeDeltaReflection = 1u << 2,
    kLobeDiffuseTransmission = 1u << 3,
    kLobeGlossyTransmission = 1u << 4,
    kLobeDeltaTransmission = 1u << 5,
    // Passes light on unchanged (wi = -wo, weight 1): an index-matched boundary that only
    // separates two media (the `null` BSDF).
    kLobeNull = 1u << 6,
    kLobeDelta = kLobeDeltaReflection | kLobeDeltaTransmission | kLobeNull,
    kLobeTransmission =
        kLobeDiffuseTransmission | kLobeGlossyTransmission | kLobeDeltaTransmission | kLobeNull,
    kLobeNonDelta = kLobeDiffuseReflection | kLobeGlossyReflection | kLobeDiffuseTransmission |
                    kLobeGlossyTransmission,
};

// Both directional densities of one pair of directions, in solid angle (fields of this type are
// named pdf_w):
// forward = p(wi | wo), the density with which sample(wo) produces wi;
// reverse = p(wo | wi), the density with which sample(wi) would produce wo.
// Bidirectional MIS needs both; they differ for every non-symmetric sampling scheme.
struct BsdfPdf {
    float forward = 0;
    float reverse = 0;
};

// f and both directional densities of one direction pair (BsdfPdf's conventions).
struct BsdfEvaluation {
    Rgb f;
    BsdfPdf pdf_w;
};

struct BsdfSample {
    Vec3 wi;
    // f(wo, wi) * |cos(wi)| / pdf_w.forward, including the lobe selection probability. For a
    // delta lobe it is the lobe's throughput divided by its selection probability.
    Rgb weight;
    // Solid-angle densities as in BsdfPdf. For delta lobes these are instead the discrete lobe
    // selection probabilities (the convention of SmallVCM), and `delta` is true.
    BsdfPdf pdf_w;
    bool delta = false;
    uint32_t lobe = kLobeNone;
    // Relative IOR along the sampled direction (eta_inside/eta_outside when entering), 1 for
    // reflection. Used by Russian roulette and by radiance scaling diagnostics.
    float eta = 1.0f;
};

class Bsdf : public std::enable_shared_from_this<Bsdf> {
  public:
    virtual ~Bsdf() = default;

    // A material with textured parameters varies over the surface: the scene resolves it at
    // every hit into the plain BSDF of that point (textured_bsdf.h), which is what
    // SurfaceInteraction::bsdf then points to. Plain BSDFs return null.
    bool varies() const { return varies_; }
    virtual std::shared_ptr<const Bsdf> at(Vec2 /*uv*/) const { return nullptr; }
    // Built by at() for one hit and owned by shared pointers only: whoever keeps it beyond the
    // interaction (SurfaceBsdf) shares its ownership.
    bool built_for_hit() const { return built_for_hit_; }

    // The shading frame at a hit of this material, given the shape's shading frame, uv and
    // dp/du, dp/dv (world space): the same frame but for a normal or bump map (normal_map.h,
    // bump_map.h). Asked only of materials that vary, before at() (Scene::intersect).
    virtual Frame shading_frame(const SurfaceInteraction& si) const { return si.shading; }
    // True for materials whose shading_frame changes the frame: they must be outermost (a
    // wrapper resolves its children with at(), which drops the frame).
    virtual bool changes_shading_frame() const { return false; }

    // f(wo, wi) without the cosine factor. Zero for delta lobes.
    virtual Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const = 0;

    // Solid-angle densities of sample() for the non-delta lobes. Zero for delta lobes.
    virtual BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const = 0;

    // f and pdf_w of one pair in one call: connections and merges need both. A model whose two
    // share work (Phong's power of the lobe cosine) overrides it; an override returns exactly
    // what the two calls return, bit for bit (the images do not depend on which is called).
    virtual BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
        return {f(wo, wi, mode), pdf_w(wo, wi)};
    }

    // Samples wi given wo. `u_lobe` picks a lobe, `u` samples within it. Returns nothing when
    // the sample is invalid (below the surface, total internal reflection with zero weight...).
    virtual std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                             TransportMode mode) const = 0;

    // Union of the lobes this BSDF has.
    virtual uint32_t lobes() const = 0;

    bool is_delta() const { return (lobes() & kLobeNonDelta) == 0; }
    bool has_non_delta() const { return (lobes() & kLobeNonDelta) != 0; }
    bool has_delta() const { return (lobes() & kLobeDelta) != 0; }
    // Index-matched boundary: paths cross it without scattering (media transitions only).
    bool is_null() const { return lobes() == kLobeNull; }

    // A short description for logs and error messages.
    virtual std::string to_string() const = 0;

  protected:
    bool varies_ = false;

  private:
    friend class TexturedBsdf;
    bool built_for_hit_ = false;
};

}  // namespace render
