#pragma once

// Registry from scene-file texture names ("bitmap", "checkerboard") to classes, and the
// reader every textured parameter shares.

#include <memory>
#include <string>

#include "core/base/properties.h"
#include "core/textures/texture.h"

namespace render {

// Builds the texture that props.type() names. Throws SceneError (naming file, line and
// parameter) for an unknown type, a missing or unreadable file or an invalid parameter; the
// caller checks for unused parameters afterwards.
std::shared_ptr<const Texture> make_texture(const Properties& props);

// Parameter `name` as a texture: the nested or referenced <texture>, or a constant texture of
// the rgb or float given (`def` when absent).
std::shared_ptr<const Texture> read_texture(const Properties& props, const std::string& name,
                                            const Rgb& def);

}  // namespace render
