#pragma once

// Registry from scene-file BSDF names ("diffuse", "roughconductor", ...) to classes.

#include <memory>

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

// Builds the BSDF that props.type() names. Wrappers (twosided) take their child from
// props.nested_bsdfs. Throws SceneError (naming file, line and field) for an unknown type or
// an invalid parameter; the caller checks for unused parameters afterwards.
std::shared_ptr<const Bsdf> make_bsdf(const Properties& props);

}  // namespace render
