#pragma once

// Reads the typed property elements of a plugin (integer, float, boolean, string, rgb,
// spectrum, point, vector, transform) into its Properties. Reference:
// docs/reference/scene-format.md.

#include <string>
#include <string_view>

#include "core/base/properties.h"
#include "core/math/transform.h"
#include "core/scene/loader/xml_element.h"

namespace render {

bool is_property_tag(std::string_view tag);

// Adds the value of property element `e` to `props`; throws SceneError naming the file, line
// and field for a malformed value.
void read_property(const XmlElement& e, Properties& props);

// <spectrum name="n" filename="f"/> with the file's `text` (read by the loader, which resolves
// and confines the name): lines "wavelength value" (nm; whitespace or a comma between; `#`
// starts a comment; blank lines skipped), converted as a wavelength:value list. Errors name
// `file_name` and its line.
void read_spectrum_file(const XmlElement& e, const std::string& text, const std::string& file_name,
                        Properties& props);

// A <transform> element's children (matrix, lookat, translate, scale, rotate) composed in file
// order: each one is applied after the previous ones (T = next * T).
Transform read_transform(const XmlElement& e);

}  // namespace render
