// Instancing: <shape type="shapegroup"> defines a group once, <shape type="instance"> places
// it (core/shapes/instance.h).

#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {

// <shape type="shapegroup" id="..."> with <shape> children: defined once, placed by
// instances (core/shapes/instance.h). Its shapes are in the group's own space.
void Loader::read_shapegroup(const XmlElement& e) {
    if (open_group_)
        throw SceneError(e.where(), "a shapegroup cannot be nested in another shapegroup");
    e.check_attributes({"type", "id", "name"});
    const std::optional<std::string> id = e.optional("id");
    if (!id || id->empty())
        throw SceneError(e.where(), "a shapegroup needs an id (instances refer to it)");
    // (A failed load discards the loader, so open_group_ needs no reset on errors.)
    auto group = std::make_shared<ShapeGroup>(*id);
    open_group_ = group.get();
    for (const XmlElement& c : e.children()) {
        if (c.tag() != "shape") {
            if (is_property_tag(c.tag()))
                throw SceneError(c.where(), "shapegroup \"" + *id +
                                                "\": a shapegroup takes no parameters (only "
                                                "<shape> children)");
            unknown_tag(c, e.describe());
        }
        const std::optional<std::string> type = c.optional("type");
        if (type && (*type == "shapegroup" || *type == "instance"))
            throw SceneError(c.where(), "a " + *type +
                                            " inside a shapegroup is not supported (nested "
                                            "instancing)");
        read_shape(c);
    }
    open_group_ = nullptr;
    if (group->empty()) throw SceneError(e.where(), "shapegroup \"" + *id + "\" has no shapes");
    register_id(*id, e.where());
    groups_[*id] = std::move(group);
}

// <shape type="instance"> with a <ref id="group"/> and an optional to_world.
void Loader::read_instance(const XmlElement& e) {
    std::shared_ptr<const ShapeGroup> group;
    Properties props = read_object(e, "shape", [&](const XmlElement& c, Properties&) {
        if (c.tag() != "ref") return false;
        c.check_attributes({"id", "name"});
        if (!c.children().empty()) throw SceneError(c.where(), "<ref> cannot have child elements");
        if (group) throw SceneError(c.where(), "an instance refers to one shapegroup");
        const std::string id = c.required("id");
        auto it = groups_.find(id);
        if (it == groups_.end())
            throw SceneError(c.where(), ids_.count(id) ? "<ref id=\"" + id + "\">: \"" + id +
                                                             "\" is not a shapegroup (an instance "
                                                             "takes no bsdf, emitter or medium)"
                                                       : "<ref>: unknown shapegroup \"" + id +
                                                             "\" (it must be defined before its "
                                                             "instances)");
        group = it->second;
        return true;
    });
    if (!group) throw SceneError(e.where(), "an instance needs <ref id=\"...\"/> to a shapegroup");
    if (!props.id.empty()) register_id(props.id, e.where());
    std::unique_ptr<Instance> instance = build(props, [&] {
        const Transform to_world = props.get_ray_transform("to_world");
        return std::make_unique<Instance>(
            group, to_world,
            props.id.empty() ? "instance (" + e.where().to_string() + ")" : props.id);
    });
    if (!within_scene_limits(*instance))
        throw SceneError(e.where(), e.describe() +
                                        ": its geometry reaches beyond 1e12 from the origin "
                                        "or is not finite (check its to_world transform)");
    scene_.add_instance(std::move(instance));
}

}  // namespace render::mitsuba
