#pragma once

// An element of a scene file as the loader sees it: attribute values with $name substitution
// applied, strict attribute checks, and source locations for messages.

#include <pugixml.hpp>

#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/scene/loader/xml_file.h"

namespace render {

using ParameterTable = std::map<std::string, std::string>;

// Replaces every $name (name = letters, digits, underscores) by its value; an undefined name is
// an error at `where`.
std::string substitute_parameters(std::string_view value, const ParameterTable& params,
                                  const SourceLocation& where);

class XmlElement {
  public:
    XmlElement(pugi::xml_node node, const XmlFile& file, const ParameterTable& params)
        : node_(node), file_(&file), params_(&params) {}

    std::string tag() const { return node_.name(); }
    SourceLocation where() const { return file_->where(node_); }
    const XmlFile& file() const { return *file_; }

    // Throws for an attribute that is not in `allowed`.
    void check_attributes(std::initializer_list<std::string_view> allowed) const;
    bool has(const char* name) const { return bool(node_.attribute(name)); }
    // The substituted value; required() throws when the attribute is missing.
    std::optional<std::string> optional(const char* name) const;
    std::string required(const char* name) const;
    // Element children; text content inside an element is an error.
    std::vector<XmlElement> children() const;
    // "<float name="fov">" style description for messages.
    std::string describe() const;

  private:
    pugi::xml_node node_;
    const XmlFile* file_;
    const ParameterTable* params_;
};

}  // namespace render
