#pragma once

// Readers for the parameters BSDF plugins share (reflectances, IORs, roughness), with the
// validation and error messages of the scene format in one place.

#include <string>

#include "core/base/properties.h"
#include "core/materials/ior.h"
#include "core/materials/microfacet.h"

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

// `distribution`, `alpha` or `alpha_u`/`alpha_v`, `sample_visible`.
MicrofacetDistribution read_microfacet(const Properties& props);

// `eta` and `k`, or `material` (default "none": a perfect mirror, returned as nothing).
std::optional<ConductorIor> read_conductor_ior(const Properties& props);

}  // namespace render
