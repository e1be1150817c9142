#pragma once

// Scene-file volumes (Mitsuba 3's `<volume type="...">`):
//   constvolume  value (float or rgb, default 1); to_world accepted (a constant ignores it)
//   gridvolume   filename (.vol or .vdb, relative to scene_dir), to_world (transform of the
//                unit cube, identity), filter_type ("trilinear" | "nearest"), wrap_mode
//                ("clamp" only), use_grid_bbox (boolean, false: place the grid by the file's
//                bounding box before to_world, as Mitsuba 3's option of that name)
// See grid_volume.h for the interpolation convention and docs/design/media.md.

#include <memory>
#include <string>

#include "core/base/properties.h"
#include "core/media/volume.h"

namespace render {

// Throws SceneError naming the parameter's line for an unknown type, a missing or malformed
// file (bad header, wrong sizes, NaN, infinite or negative values) or a bad parameter.
std::shared_ptr<const Volume> make_volume(const Properties& props, const std::string& scene_dir);

}  // namespace render
