// <medium> elements with their <phase> and <volume>s, and <ref>s to a medium.

#include "core/media/medium_factory.h"
#include "core/media/volume_factory.h"
#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {

std::shared_ptr<const PhaseFunction> Loader::read_phase(const XmlElement& e) {
    Properties props = read_plain_object(e, "phase");
    return build(props, [&] { return make_phase(props); });
}

std::shared_ptr<const Volume> Loader::read_volume(const XmlElement& e) {
    Properties props = read_plain_object(e, "volume");
    return build(props, [&] { return make_volume(props, e.file().dir().string()); });
}

// <medium type="..."> with an optional nested <phase> and nested <volume name="...">.
const Medium* Loader::read_medium_object(const XmlElement& e) {
    std::shared_ptr<const PhaseFunction> phase;
    std::map<std::string, std::shared_ptr<const Volume>> volumes;
    Properties props = read_object(e, "medium", [&](const XmlElement& c, Properties&) {
        if (c.tag() == "phase") {
            if (phase) throw SceneError(c.where(), "a medium has at most one <phase>");
            phase = read_phase(c);
            return true;
        }
        if (c.tag() == "volume") {
            const std::string name = c.required("name");
            if (volumes.count(name))
                throw SceneError(c.where(), "volume \"" + name + "\" is given twice");
            volumes[name] = read_volume(c);
            return true;
        }
        return false;
    });
    std::shared_ptr<const Medium> medium =
        build(props, [&] { return make_medium(props, phase, volumes); });
    if (!medium) throw SceneError(e.where(), "medium \"" + props.type() + "\" was not built");
    if (!props.id.empty()) {
        register_id(props.id, e.where());
        media_[props.id] = medium.get();
    }
    const std::string name = (props.id.empty() ? "medium" : "medium \"" + props.id + "\"") + " (" +
                             e.where().to_string() + ")";
    return scene_.add_medium(std::move(medium), name);
}

const Medium* Loader::lookup_medium(const XmlElement& ref) {
    const std::string id = ref.required("id");
    auto it = media_.find(id);
    if (it == media_.end()) {
        if (ids_.count(id))
            throw SceneError(ref.where(),
                             "<ref id=\"" + id + "\">: \"" + id + "\" is not a medium");
        throw SceneError(ref.where(), "<ref>: unknown medium \"" + id +
                                          "\" (a medium must be defined before it is "
                                          "referenced)");
    }
    return it->second;
}

}  // namespace render::mitsuba
