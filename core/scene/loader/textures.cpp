// <texture> elements: top-level (with an id, for <ref>) and nested as a plugin's parameter.

#include "core/scene/loader/xml_loader.h"
#include "core/textures/texture_factory.h"

namespace render::mitsuba {

// <texture type="..."> at the top level (with an id, for <ref>) or nested in a plugin
// (with the name of the parameter it gives). Textures nest: checkerboard's colours.
std::shared_ptr<const Texture> Loader::read_texture_object(const XmlElement& e) {
    Properties props = read_object(
        e, "texture", [&](const XmlElement& c, Properties& p) { return read_texture_child(c, p); });
    std::shared_ptr<const Texture> texture = build(props, [&] { return make_texture(props); });
    if (!props.id.empty()) {
        register_id(props.id, e.where());
        textures_[props.id] = texture;
    }
    return texture;
}

// A plugin's child that gives a texture parameter: a nested <texture name="..."> or a
// <ref name="..." id="..."/> to a texture. False for any other child (a <ref> to something
// else included), which the plugin's reader then handles.
bool Loader::read_texture_child(const XmlElement& c, Properties& p) {
    if (c.tag() == "texture") {
        const std::optional<std::string> name = c.optional("name");
        if (!name || name->empty())
            throw SceneError(c.where(), "a <texture> inside " + p.plugin_class() + " \"" +
                                            p.type() +
                                            "\" needs name=\"parameter\" (e.g. "
                                            "name=\"reflectance\")");
        p.set(*name, read_texture_object(c), c.where());
        return true;
    }
    if (c.tag() != "ref") return false;
    const std::optional<std::string> id = c.optional("id");
    if (!id) return false;
    auto it = textures_.find(*id);
    if (it == textures_.end()) return false;
    c.check_attributes({"id", "name"});
    if (!c.children().empty()) throw SceneError(c.where(), "<ref> cannot have child elements");
    const std::optional<std::string> name = c.optional("name");
    if (!name || name->empty())
        throw SceneError(c.where(), "<ref id=\"" + *id +
                                        "\">: a texture reference needs name=\"parameter\" "
                                        "(e.g. name=\"reflectance\")");
    p.set(*name, it->second, c.where());
    return true;
}

}  // namespace render::mitsuba
