// <bsdf> elements (top-level, nested, wrapped), <ref>s to them, and the BSDFs a shape gets
// without one: Mitsuba's default diffuse and, for a media boundary, the null BSDF.

#include "core/materials/bsdf_factory.h"
#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {

std::shared_ptr<const Bsdf> Loader::read_bsdf_object(const XmlElement& e) {
    Properties props = read_object(e, "bsdf", [&](const XmlElement& c, Properties& p) {
        if (c.tag() == "bsdf") {
            p.nested_bsdfs.push_back(read_bsdf_object(c));
            return true;
        }
        if (read_texture_child(c, p)) return true;
        if (c.tag() == "ref") {
            if (!c.children().empty())
                throw SceneError(c.where(), "<ref> cannot have child elements");
            p.nested_bsdfs.push_back(lookup_bsdf(c));
            return true;
        }
        return false;
    });
    refuse_nested_normal_maps(props);
    std::shared_ptr<const Bsdf> bsdf = build(props, [&] { return make_bsdf(props); });
    if (!bsdf) throw SceneError(e.where(), "bsdf \"" + props.type() + "\" was not built");
    if (!props.id.empty()) {
        register_id(props.id, e.where());
        bsdfs_[props.id] = bsdf;
    }
    return bsdf;
}

void Loader::read_bsdf(const XmlElement& e) {
    keep(read_bsdf_object(e));
}

// A wrapper resolves its children at a hit without their shading frame, so a normal or bump
// map must be the outermost bsdf (Mitsuba's examples write it so: normalmap around
// twosided).
void Loader::refuse_nested_normal_maps(const Properties& props) {
    if (props.type() == "normalmap" || props.type() == "bumpmap")
        return;  // they refuse a nested one themselves
    for (const auto& nested : props.nested_bsdfs)
        if (nested->changes_shading_frame())
            throw SceneError(props.where(), "bsdf \"" + props.type() +
                                                "\" cannot wrap a normalmap or bumpmap: "
                                                "write the map around it instead");
}

std::shared_ptr<const Bsdf> Loader::lookup_bsdf(const XmlElement& ref) {
    ref.check_attributes({"id", "name"});
    std::string id = ref.required("id");
    auto it = bsdfs_.find(id);
    if (it == bsdfs_.end()) {
        if (ids_.count(id))
            throw SceneError(ref.where(), "<ref id=\"" + id + "\">: \"" + id + "\" is not a bsdf");
        throw SceneError(ref.where(), "<ref>: unknown id \"" + id +
                                          "\" (a bsdf must be defined before it is "
                                          "referenced)");
    }
    return it->second;
}

// Hands a BSDF to the scene once, however many shapes use it.
const Bsdf* Loader::keep(std::shared_ptr<const Bsdf> bsdf) {
    if (kept_.insert(bsdf.get()).second) scene_.add_bsdf(bsdf);
    return bsdf.get();
}

const Bsdf* Loader::default_bsdf(const SourceLocation& where) {
    if (!default_bsdf_) {
        // A shape without a BSDF gets Mitsuba 3's default: diffuse with reflectance 0.5.
        Properties props("bsdf", "diffuse", where);
        default_bsdf_ = keep(build(props, [&] { return make_bsdf(props); }));
    }
    return default_bsdf_;
}

const Bsdf* Loader::null_bsdf(const SourceLocation& where) {
    if (!null_bsdf_) {
        Properties props("bsdf", "null", where);
        null_bsdf_ = keep(build(props, [&] { return make_bsdf(props); }));
    }
    return null_bsdf_;
}

}  // namespace render::mitsuba
