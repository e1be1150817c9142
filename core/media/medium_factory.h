#pragma once

// Registry from scene-file names to phase functions and media (Mitsuba 3 names and
// parameters; the 0.6 forms of `homogeneous` are accepted too). See docs/reference/scene-format.md.

#include <map>
#include <memory>
#include <string>

#include "core/base/properties.h"
#include "core/media/medium.h"
#include "core/media/phase_function.h"

namespace render {

class Volume;

// `isotropic`, `hg` (parameter g in (-1, 1)).
std::shared_ptr<const PhaseFunction> make_phase(const Properties& props);

// `homogeneous` and `heterogeneous`. `phase` is the nested phase function (isotropic when
// absent); `volumes` the nested <volume name="..."> children by name.
std::shared_ptr<const Medium> make_medium(
    const Properties& props, std::shared_ptr<const PhaseFunction> phase,
    const std::map<std::string, std::shared_ptr<const Volume>>& volumes);

}  // namespace render
