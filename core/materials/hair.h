#pragma once

// pbrt-v4's `hair`: the fibre scattering model of Chiang, Bitterli, Tappan and Burley 2016, "A
// Practical and Controllable Hair and Fur Model for Production Path Tracing", as pbrt-v4
// (section 9.9) evaluates and samples it. The fibre is a dielectric cylinder (index eta) with
// absorption sigma_a inside; light leaves it after p = 0 (R), 1 (TT), 2 (TRT) and >= 3 internal
// paths, each term the product of
//   Mp  longitudinal scattering (d'Eon et al. 2011's formulation, variance from beta_m),
//   Ap  attenuation by Fresnel reflection and absorption,
//   Np  azimuthal scattering (a logistic trimmed to [-pi, pi], scale from beta_n),
// with the cuticle scales tilting the R, TT and TRT lobes by -2 alpha, alpha and 4 alpha.
//
// Local frame: x along the fibre (the curve's dp/du), z the surface normal, y = z x x. `h` in
// [-1, 1] is where across its width the camera-side ray meets the fibre, taken one of two ways:
//   HairOffset::FromHitV       pbrt-v4's: -1 + 2 v from the hit's v (curves report it,
//                              docs/reference/scene-format.md "Curves"); the material is then
//                              resolved at every hit;
//   HairOffset::FromDirection  Mitsuba 3's: from the camera-side direction and the normal, for a
//                              round fibre whose normal is the true one: h = sin(phi_o - phi_n)
//                              = -w.y / |(w.y, w.z)| (the R lobe's specular geometry). A plain
//                              function of the two directions, so a proper surface BSDF.
// The model divides by |cos theta_i| so that f |cos| is the fibre's own scattering: the normal
// of a ribbon plays no role.
//
// The model is not reciprocal (Ap, Np and the scale tilts depend on wo only): Radiance mode
// evaluates it as pbrt-v4 does, with wo the camera-side direction; Importance mode evaluates the
// adjoint f(wi, wo), so that light and camera paths carry the same BSDF. With FromDirection
// that makes bidirectional methods converge to the path tracer's image exactly; with FromHitV
// a light path's hit reports the light ray's h, not the camera's (pbrt-v4 has the same
// limitation), docs/reference/scene-format.md "Curves".

#include <array>

#include <memory>

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/textures/texture.h"

namespace render {

enum class HairOffset { FromHitV, FromDirection };

struct HairParams {
    Rgb sigma_a;          // absorption per unit fibre radius
    float eta = 1.55f;    // fibre index
    float beta_m = 0.3f;  // longitudinal roughness, [0, 1]
    float beta_n = 0.3f;  // azimuthal roughness, [0, 1]
    float alpha = 2.0f;   // cuticle scale angle, degrees
};

// pbrt-v4's hair parameters given as textures, looked up at the hit's uv (null: the constant of
// HairParams, or the constants below). sigma_a comes from one of three sources, as at load.
struct HairTextures {
    enum class Absorption { SigmaA, Reflectance, Melanin };
    Absorption absorption = Absorption::SigmaA;
    std::shared_ptr<const Texture> sigma_a, reflectance, eumelanin, pheomelanin;
    std::shared_ptr<const Texture> eta, beta_m, beta_n, alpha;
    Rgb reflectance_value;                                // Reflectance without a texture
    float eumelanin_value = 1.3f, pheomelanin_value = 0;  // Melanin without textures

    bool any() const {
        return sigma_a || reflectance || eumelanin || pheomelanin || eta || beta_m || beta_n ||
               alpha;
    }
    // The parameters at uv: `constant` with the textured ones replaced, each clamped to its
    // valid range (sigma_a >= 0, eta > 0, betas in [0, 1], alpha in [-90, 90]).
    HairParams at(Vec2 uv, const HairParams& constant) const;
};

class HairBsdf final : public Bsdf {
  public:
    static constexpr int kMaxP = 3;  // terms p = 0, 1, 2 explicit; p >= 3 lumped into one

    // A fibre hit at offset h (FromHitV), or one whose offset follows the directions.
    HairBsdf(const HairParams& params, float h);
    HairBsdf(const HairParams& params, HairOffset offset);

    // Mitsuba 3's `hair` (its names and defaults): `eumelanin` (1.3) and `pheomelanin` (0.2), or
    // `sigma_a` (rgb); `scale` (1, multiplies sigma_a); `int_ior` ("amber", 1.55) and `ext_ior`
    // ("air"); `longitudinal_roughness` and `azimuthal_roughness` (0.3 each);
    // `scale_tilt` (2, degrees). h FromDirection, as Mitsuba.
    static std::shared_ptr<const Bsdf> create(const Properties& props);
    // pbrt-v4's `hair` material: h FromHitV, so the material varies over the surface and the
    // scene resolves it into a HairBsdf at every hit, with `textures` looked up there.
    static std::shared_ptr<const Bsdf> pbrt_material(const HairParams& params,
                                                     const HairTextures& textures = {});

    // pbrt-v4's conversions: sigma_a from melanin concentrations, and from the reflectance after
    // multiple scattering for a given beta_n (Chiang et al. 2016, section 4.2).
    static Rgb sigma_a_from_concentration(float eumelanin, float pheomelanin);
    static Rgb sigma_a_from_reflectance(const Rgb& reflectance, float beta_n);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeGlossyReflection | kLobeGlossyTransmission; }
    std::string to_string() const override;

    float h() const { return h_; }  // FromHitV only
    HairOffset offset() const { return offset_; }
    const HairParams& params() const { return params_; }
    // The model in pbrt-v4's orientation (wo the camera side): f |cos theta_i| is `f_cos`
    // (the fibre's scattering function), `density` what sample() draws wi with given wo.
    Rgb f_cos(const Vec3& wo, const Vec3& wi) const;
    float density(const Vec3& wo, const Vec3& wi) const;
    // The offset h for camera-side direction w.
    float h_for(const Vec3& w) const;

  private:
    // Terms of the model that depend on wo only.
    struct Outgoing {
        float sin_theta, cos_theta, phi, gamma_o, gamma_t;
        std::array<Rgb, kMaxP + 1> ap;
        std::array<float, kMaxP + 1> ap_pdf;  // term selection probabilities
        // sin and cos of theta_o tilted by the scales, per explicit term
        std::array<float, kMaxP> sin_tilted, cos_tilted;
    };
    Outgoing outgoing(const Vec3& wo) const;
    float density(const Outgoing& o, const Vec3& wi) const;

    HairParams params_;
    HairOffset offset_;
    float h_;
    std::array<float, kMaxP + 1> v_;  // longitudinal variance per term
    float s_;                         // logistic scale
    // sin and cos of 2^k alpha, k = 0, 1, 2
    std::array<float, kMaxP> sin_2k_alpha_, cos_2k_alpha_;
};

}  // namespace render
