#pragma once

// Reads the typed property elements of a plugin (integer, float, boolean, string, rgb,
// spectrum, point, vector, transform) into its Properties. Reference: docs/scene-format.md.

#include <string_view>

#include "core/base/properties.h"
#include "core/math/transform.h"
#include "core/scene/loader/xml_element.h"

namespace render {

bool is_property_tag(std::string_view tag);

// Adds the value of property element `e` to `props`; throws SceneError naming the file, line
// and field for a malformed value.
void read_property(const XmlElement& e, Properties& props);

// A <transform> element's children (matrix, lookat, translate, scale, rotate) composed in file
// order: each one is applied after the previous ones (T = next * T).
Transform read_transform(const XmlElement& e);

}  // namespace render
