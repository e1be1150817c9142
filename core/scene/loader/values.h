#pragma once

// Strict parsing of the textual values of scene-file attributes. Every function throws a
// SceneError at `where` that names `field` (e.g. `float "fov"`) for text that is not exactly a
// value of the requested kind, and for NaN or infinite numbers.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/base/error.h"

namespace render {

// A finite number that also fits a float.
double parse_number(std::string_view text, const SourceLocation& where, const std::string& field);
int64_t parse_integer(std::string_view text, const SourceLocation& where, const std::string& field);
// "true" or "false" (any case).
bool parse_boolean(std::string_view text, const SourceLocation& where, const std::string& field);
// Numbers separated by commas and/or white space.
std::vector<double> parse_number_list(std::string_view text, const SourceLocation& where,
                                      const std::string& field);

}  // namespace render
