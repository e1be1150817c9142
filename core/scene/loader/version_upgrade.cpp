#include "core/scene/loader/version_upgrade.h"

#include <cctype>
#include <cstring>

namespace render {
namespace {

struct TagRename {
    const char* from;
    const char* to;
};
// Tags renamed in format 2.0.0.
constexpr TagRename kTagRenames[] = {
    {"lookAt", "lookat"},
};

struct ParameterRename {
    const char* plugin_class;  // tag of the plugin element
    const char* plugin_type;   // its type attribute
    const char* from;          // parameter name after the snake_case conversion
    const char* to;
};
// Parameters renamed in format 2.0.0 for particular plugins.
constexpr ParameterRename kParameterRenames[] = {
    {"bsdf", "diffuse", "diffuse_reflectance", "reflectance"},
};

void upgrade_node(pugi::xml_node node) {
    for (const TagRename& r : kTagRenames)
        if (std::strcmp(node.name(), r.from) == 0) node.set_name(r.to);
    if (std::strcmp(node.name(), "default") != 0)
        if (pugi::xml_attribute name = node.attribute("name"))
            name.set_value(to_snake_case(name.value()).c_str());
    for (pugi::xml_node child : node.children())
        if (child.type() == pugi::node_element) upgrade_node(child);
    for (const ParameterRename& r : kParameterRenames) {
        if (std::strcmp(node.name(), r.plugin_class) != 0 ||
            std::strcmp(node.attribute("type").value(), r.plugin_type) != 0)
            continue;
        for (pugi::xml_node child : node.children())
            if (pugi::xml_attribute name = child.attribute("name"))
                if (std::strcmp(name.value(), r.from) == 0 &&
                    std::strcmp(child.name(), "default") != 0)
                    name.set_value(r.to);
    }
}

}  // namespace

std::string to_snake_case(const std::string& name) {
    std::string out;
    out.reserve(name.size() + 4);
    for (size_t i = 0; i < name.size(); ++i) {
        unsigned char c = static_cast<unsigned char>(name[i]);
        if (std::isupper(c)) {
            unsigned char prev = i > 0 ? static_cast<unsigned char>(name[i - 1]) : 0;
            if (i > 0 && (std::islower(prev) || std::isdigit(prev))) out.push_back('_');
            out.push_back(char(std::tolower(c)));
        } else {
            out.push_back(char(c));
        }
    }
    return out;
}

void upgrade_scene(pugi::xml_node scene, const FormatVersion& version) {
    if (!(version < FormatVersion{{2, 0, 0}})) return;
    for (pugi::xml_node child : scene.children())
        if (child.type() == pugi::node_element) upgrade_node(child);
}

}  // namespace render
