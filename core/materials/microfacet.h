#pragma once

// Microfacet normal distributions (Beckmann, GGX/Trowbridge-Reitz), optionally anisotropic,
// with the Smith shadowing-masking functions and normal sampling either from D(m) cos(m) or
// from the distribution of visible normals (Heitz 2018 for GGX; for Beckmann the slope
// inversion of Heitz & d'Eon 2014, done numerically as Jakob proposed).
//
// Micro-normals m always lie in the upper hemisphere (m.z > 0). Directions passed to
// sample()/pdf() must be in the upper hemisphere too; callers flip directions that are below.

#include <string>

#include "core/math/vec.h"

namespace render {

enum class MicrofacetType { Beckmann, GGX };

// Parses "beckmann" / "ggx"; nothing else.
bool parse_microfacet_type(const std::string& name, MicrofacetType& type);
const char* to_string(MicrofacetType type);

class MicrofacetDistribution {
  public:
    // Roughness below kMinAlpha is clamped to it: a delta lobe in disguise gives no useful
    // samples and overflows D.
    static constexpr float kMinAlpha = 1e-4f;

    MicrofacetDistribution(MicrofacetType type, float alpha_u, float alpha_v,
                           bool sample_visible = true);

    MicrofacetType type() const { return type_; }
    float alpha_u() const { return alpha_u_; }
    float alpha_v() const { return alpha_v_; }
    bool sample_visible() const { return sample_visible_; }
    bool is_isotropic() const { return alpha_u_ == alpha_v_; }

    // Density of micro-normals per unit solid angle and unit projected area: the integral of
    // D(m) cos(theta_m) over the hemisphere is 1.
    float D(const Vec3& m) const;

    // Smith's auxiliary function: G1(w) = 1 / (1 + lambda(w)) for unmasked facets.
    float lambda(const Vec3& w) const;

    // Masking of micro-normal m seen from w (either hemisphere); 0 when m faces away from w.
    float G1(const Vec3& w, const Vec3& m) const;

    // Separable Smith shadowing-masking, as Mitsuba uses.
    float G(const Vec3& wo, const Vec3& wi, const Vec3& m) const { return G1(wo, m) * G1(wi, m); }

    // Samples a micro-normal for a path arriving from w (w.z > 0).
    Vec3 sample(const Vec3& w, Vec2 u) const;

    // Density of sample(w) at m, per unit solid angle of m.
    float pdf(const Vec3& w, const Vec3& m) const;

  private:
    // Slope of a unit-roughness visible normal for incidence angle theta (given as
    // cos/sin), with the incident direction's azimuth along +x.
    Vec2 sample_visible_slope_unit(float cos_theta, float sin_theta, Vec2 u) const;

    MicrofacetType type_;
    float alpha_u_, alpha_v_;
    bool sample_visible_;
};

// Inverse error function (double precision: Giles' approximation refined by Newton steps).
double erfinv(double y);

}  // namespace render
