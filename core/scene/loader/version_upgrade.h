#pragma once

// Upgrades a scene written for an older format version in place, as Mitsuba 3 does for files
// with version < 2.0.0: camelCase parameter names become snake_case (toWorld -> to_world,
// intIOR -> int_ior, sampleCount -> sample_count, ...), renamed tags (lookAt -> lookat) and
// renamed parameters of particular plugins (a `diffuse` bsdf's diffuse_reflectance ->
// reflectance). The tables are in version_upgrade.cpp; docs/reference/scene-format.md lists them.

#include <pugixml.hpp>

#include <string>

#include "core/scene/loader/xml_file.h"

namespace render {

// "diffuseReflectance" -> "diffuse_reflectance", "intIOR" -> "int_ior": an underscore before
// every upper-case letter that follows a lower-case letter or digit, then all lower case.
std::string to_snake_case(const std::string& name);

void upgrade_scene(pugi::xml_node scene, const FormatVersion& version);

}  // namespace render
