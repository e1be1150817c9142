#pragma once

// Named indices of refraction: Mitsuba's table of dielectrics (at ~589 nm) and RGB complex
// indices of a few common metals.

#include <optional>
#include <string>
#include <vector>

#include "core/math/vec.h"

namespace render {

// Refractive index of a named dielectric ("bk7", "water", "carbon dioxide"...), case
// insensitive; nothing when the name is unknown.
std::optional<float> lookup_dielectric_ior(const std::string& name);
// The known names, for error messages.
std::vector<std::string> dielectric_ior_names();

// Complex index eta + i k of a conductor, per RGB channel.
struct ConductorIor {
    Rgb eta;
    Rgb k;
};
// "Au", "Ag", "Cu", "Al", "Cr" (case sensitive, as chemical symbols are).
std::optional<ConductorIor> lookup_conductor_ior(const std::string& name);
std::vector<std::string> conductor_names();

}  // namespace render
