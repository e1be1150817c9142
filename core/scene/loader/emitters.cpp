// Top-level <emitter>s and named area emitters (<emitter type="area" id="...">, which shapes
// attach with <ref>).

#include "core/lights/light_factory.h"
#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {

bool Loader::is_named_area_emitter(const XmlElement& e) {
    return e.tag() == "emitter" && e.optional("type") == "area" && e.has("id");
}

// `<emitter type="area" id="X">` outside a shape defines an emitter that shapes attach
// with `<ref id="X"/>`; each referencing shape builds its own light from these values.
const Properties& Loader::read_named_area_emitter(const XmlElement& e) {
    Properties props = read_object(
        e, "emitter", [&](const XmlElement& t, Properties& p) { return read_texture_child(t, p); });
    register_id(props.id, e.where());
    return area_emitters_.emplace(props.id, std::move(props)).first->second;
}

// The named area emitter `id`, read now if it is defined later in an open file.
const Properties* Loader::find_area_emitter(const std::string& id) {
    if (auto it = area_emitters_.find(id); it != area_emitters_.end()) return &it->second;
    if (auto it = pending_area_emitters_.find(id); it != pending_area_emitters_.end()) {
        read_ahead_.insert(id);
        return &read_named_area_emitter(it->second);
    }
    return nullptr;
}

void Loader::read_top_level_emitter(const XmlElement& e) {
    if (is_named_area_emitter(e)) {
        // Already read when a shape referenced it before its definition.
        if (!read_ahead_.erase(*e.optional("id"))) read_named_area_emitter(e);
        return;
    }
    // A nested medium (or a reference to one) is the medium the light sits in.
    const Medium* medium = nullptr;
    Properties props = read_object(e, "emitter", [&](const XmlElement& c, Properties& p) {
        if (read_texture_child(c, p)) return true;
        if (c.tag() != "medium" && c.tag() != "ref") return false;
        if (medium) throw SceneError(c.where(), "an emitter sits in one medium only");
        if (c.tag() == "ref") c.check_attributes({"id", "name"});
        medium = c.tag() == "medium" ? read_medium_object(c) : lookup_medium(c);
        return true;
    });
    if (props.type() == "area")
        throw SceneError(e.where(), "an area emitter must be nested in a <shape>");
    std::unique_ptr<Light> light =
        build(props, [&] { return make_light(props, nullptr, e.file().dir()); });
    if (!light) throw SceneError(e.where(), "emitter \"" + props.type() + "\" was not built");
    if (!props.id.empty()) register_id(props.id, e.where());
    light->medium = medium;
    scene_.add_light(std::move(light));
}

}  // namespace render::mitsuba
