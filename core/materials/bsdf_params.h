#pragma once

// Readers for the parameters BSDF plugins share (reflectances, IORs, roughness), with the
// validation and error messages of the scene format in one place.

#include <string>

#include "core/base/properties.h"
#include "core/materials/ior.h"
#include "core/materials/microfacet.h"
#include "core/textures/texture_param.h"

namespace render {

// A finite, non-negative RGB or float reflectance.
Rgb read_reflectance(const Properties& props, const std::string& name, const Rgb& def);

// A finite, non-negative float.
float read_non_negative(const Properties& props, const std::string& name, float def);

// A refractive index given as a number (> 0) or as a name from the IOR table.
float read_ior(const Properties& props, const std::string& name, float def);

// int_ior / ext_ior with Mitsuba's defaults for `int_default` (bk7 for glass, polypropylene for
// plastic) and air outside.
float read_relative_ior(const Properties& props, float int_default);

// A finite, non-negative RGB or float reflectance, or a texture whose values all are.
RgbParam read_reflectance_param(const Properties& props, const std::string& name, const Rgb& def);

// The microfacet parameters of rough BSDFs, each roughness a constant or a texture.
struct MicrofacetParams {
    MicrofacetType type = MicrofacetType::Beckmann;
    FloatParam alpha_u, alpha_v;  // alpha_v unused when isotropic (one `alpha`)
    bool isotropic = false;
    bool sample_visible = true;

    bool varies() const { return alpha_u.varies() || (!isotropic && alpha_v.varies()); }
    MicrofacetDistribution at(Vec2 uv) const;
    MicrofacetDistribution mean() const;  // from the textures' mean roughness
    MicrofacetDistribution at(const Vec2* uv) const { return uv ? at(*uv) : mean(); }
};

// `distribution`, `alpha` or `alpha_u`/`alpha_v` (each a float or a texture), `sample_visible`.
MicrofacetParams read_microfacet_params(const Properties& props);

// `eta` and `k`, or `material` (default "none": a perfect mirror, returned as nothing).
std::optional<ConductorIor> read_conductor_ior(const Properties& props);

}  // namespace render
