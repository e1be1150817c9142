#include "core/scene/loader/xml_element.h"

#include <cctype>

namespace render {

std::string substitute_parameters(std::string_view value, const ParameterTable& params,
                                  const SourceLocation& where) {
    std::string out;
    size_t i = 0;
    while (i < value.size()) {
        char c = value[i];
        if (c != '$') {
            out.push_back(c);
            ++i;
            continue;
        }
        size_t start = ++i;
        while (i < value.size() &&
               (std::isalnum(static_cast<unsigned char>(value[i])) || value[i] == '_'))
            ++i;
        std::string name(value.substr(start, i - start));
        if (name.empty()) throw SceneError(where, "\"$\" without a parameter name");
        auto it = params.find(name);
        if (it == params.end())
            throw SceneError(where, "undefined parameter \"$" + name +
                                        "\" (declare it with <default name=\"" + name +
                                        "\" value=\"...\"/> or pass -D " + name + "=...)");
        out += it->second;
    }
    return out;
}

void XmlElement::check_attributes(std::initializer_list<std::string_view> allowed) const {
    for (pugi::xml_attribute a : node_.attributes()) {
        bool ok = false;
        for (std::string_view name : allowed) ok = ok || name == a.name();
        if (!ok)
            throw SceneError(
                where(), "unknown attribute \"" + std::string(a.name()) + "\" on " + describe());
    }
}

std::optional<std::string> XmlElement::optional(const char* name) const {
    pugi::xml_attribute a = node_.attribute(name);
    if (!a) return std::nullopt;
    return substitute_parameters(a.value(), *params_, where());
}

std::string XmlElement::required(const char* name) const {
    std::optional<std::string> v = optional(name);
    if (!v)
        throw SceneError(where(), describe() + " needs a \"" + std::string(name) + "\" attribute");
    return *v;
}

std::vector<XmlElement> XmlElement::children() const {
    std::vector<XmlElement> out;
    for (pugi::xml_node n : node_.children()) {
        if (n.type() == pugi::node_element) {
            out.emplace_back(n, *file_, *params_);
        } else if (n.type() == pugi::node_pcdata || n.type() == pugi::node_cdata) {
            throw SceneError(file_->where(n), "unexpected text inside " + describe());
        }
    }
    return out;
}

std::string XmlElement::describe() const {
    // Built with append: GCC 12 warns (-Wrestrict, a false positive) on "literal" + string&&.
    std::string s("<");
    s.append(node_.name());
    for (const char* attr : {"type", "name", "id"}) {
        if (pugi::xml_attribute a = node_.attribute(attr)) {
            s.append(" ").append(attr).append("=\"").append(a.value()).append("\"");
        }
    }
    s.append(">");
    return s;
}

}  // namespace render
