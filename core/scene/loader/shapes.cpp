// <shape> elements with their bsdf, area emitter and interior/exterior media.

#include "core/lights/light_factory.h"
#include "core/scene/loader/shape_factory.h"
#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {

void Loader::read_shape(const XmlElement& e) {
    if (const std::optional<std::string> type = e.optional("type")) {
        if (*type == "shapegroup") return read_shapegroup(e);
        if (*type == "instance") return read_instance(e);
    }
    const Medium* interior = nullptr;
    const Medium* exterior = nullptr;
    bool has_interface = false;
    // `<ref name="interior|exterior" id="..."/>` or a nested `<medium name="...">`.
    auto set_medium = [&](const XmlElement& c, const Medium* medium) {
        const std::string name = c.required("name");
        const Medium*& slot = name == "interior" ? interior : exterior;
        if (slot || (name != "interior" && name != "exterior"))
            throw SceneError(c.where(), name == "interior" || name == "exterior"
                                            ? "the shape's " + name + " medium is given twice"
                                            : "a medium inside a <shape> needs name="
                                              "\"interior\" or name=\"exterior\"");
        slot = medium;
        has_interface = true;
    };
    std::shared_ptr<const Bsdf> bsdf;
    SourceLocation bsdf_where;
    std::optional<Properties> emitter;
    auto set_bsdf = [&](std::shared_ptr<const Bsdf> b, const XmlElement& c) {
        if (bsdf)
            throw SceneError(c.where(), "a shape has at most one bsdf (first at " +
                                            bsdf_where.to_string() + ")");
        bsdf = std::move(b);
        bsdf_where = c.where();
    };
    Properties props = read_object(e, "shape", [&](const XmlElement& c, Properties&) {
        if (c.tag() == "bsdf") {
            set_bsdf(read_bsdf_object(c), c);
            return true;
        }
        if (c.tag() == "ref") {
            if (!c.children().empty())
                throw SceneError(c.where(), "<ref> cannot have child elements");
            c.check_attributes({"id", "name"});
            std::optional<std::string> name = c.optional("name");
            if (name && (*name == "interior" || *name == "exterior")) {
                set_medium(c, lookup_medium(c));
            } else if (const Properties* named = find_area_emitter(c.required("id"))) {
                if (emitter) throw SceneError(c.where(), "a shape has at most one emitter");
                emitter = *named;
            } else {
                set_bsdf(lookup_bsdf(c), c);
            }
            return true;
        }
        if (c.tag() == "medium") {
            set_medium(c, read_medium_object(c));
            return true;
        }
        if (c.tag() == "emitter") {
            if (emitter) throw SceneError(c.where(), "a shape has at most one emitter");
            // The area light's radiance may be a texture.
            emitter = read_object(c, "emitter", [&](const XmlElement& t, Properties& p) {
                return read_texture_child(t, p);
            });
            if (emitter->type() != "area")
                throw SceneError(c.where(),
                                 "an emitter inside a <shape> must be of type "
                                 "\"area\", not \"" +
                                     emitter->type() + "\"");
            return true;
        }
        return false;
    });
    if (!props.id.empty()) register_id(props.id, e.where());
    if (open_group_ && emitter)
        throw SceneError(emitter->where(),
                         "an emitter inside a shapegroup is not supported (instances cannot "
                         "emit, as in Mitsuba)");
    if (emitter && (props.type() == "bsplinecurve" || props.type() == "linearcurve"))
        throw SceneError(emitter->where(),
                         "an area emitter on a curve is not supported (a curve has no area "
                         "sampling whose density a hit can find again)");
    std::unique_ptr<Shape> shape = build(props, [&] { return make_shape(props, e.file().dir()); });
    check_shape_extent(*shape, e);
    std::unique_ptr<Light> light;
    if (emitter) {
        light = build(*emitter, [&] { return make_light(*emitter, shape.get(), e.file().dir()); });
        if (!light) throw SceneError(emitter->where(), "the area emitter was not built");
        shape->emitter = light.get();
        light->medium = exterior;  // an area light emits on its normal's side
    }
    shape->interior = interior;
    shape->exterior = exterior;
    // A shape that only bounds media (no BSDF) is an index-matched boundary.
    const Bsdf* b = bsdf            ? keep(bsdf)
                    : has_interface ? null_bsdf(e.where())
                                    : default_bsdf(e.where());
    if (open_group_) return open_group_->add(std::move(shape), b);
    scene_.add_shape(std::move(shape), b);
    if (light) scene_.add_light(std::move(light));
}

// Refuses geometry beyond the scene's limits (within_scene_limits, core/scene/scene.h).
void Loader::check_shape_extent(const Shape& shape, const XmlElement& e) {
    if (!within_scene_limits(shape))
        throw SceneError(e.where(), e.describe() +
                                        ": its geometry reaches beyond 1e12 from the origin "
                                        "or is not finite (check its to_world transform)");
}

}  // namespace render::mitsuba
