// pbrt-v4 lights as the emitters of the Mitsuba loader (make_light). pbrt-v4 renders
// spectrally: an RGB emission becomes an illuminant spectrum (the colour's albedo spectrum
// times the colour space's D65), and every light divides its `scale` by that spectrum's
// photometric value so that RGB (1, 1, 1) is a 1-nit white, which pbrt's RGB film records as
// (1, 1, 1). An RGB renderer therefore emits the RGB value times `scale`, unchanged.

#include <cmath>

#include "core/base/properties.h"
#include "core/lights/light_factory.h"
#include "core/math/constants.h"
#include "core/scene/pbrt/builders.h"

namespace render::pbrt {
namespace {

// The emitted colour `name` times `scale` (pbrt's defaults: the colour space's white, 1).
Rgb emission(const ParamList& params, const char* name) {
    if (params.has("power"))
        throw params.error("power", "lights given by their power are not supported yet (use " +
                                        std::string(name) + " and scale)");
    if (params.type_of(name) == "blackbody")
        throw params.error(name, "blackbody emission is not supported yet (give rgb)");
    const Rgb colour = get_rgb(params, name).value_or(Rgb(1.0f));
    const double scale = params.get_float("scale", 1.0);
    if (!(scale >= 0)) throw params.error("scale", "must be non-negative");
    return colour * float(scale);
}

Vec3 position(const Transform& t, const ParamList& params, const char* name, const Vec3& def) {
    const Vec3 p = t.apply_point(params.get_point3(name, def));
    if (!is_finite(p)) throw params.error(name, "the transformed point is not finite");
    return p;
}

}  // namespace

std::unique_ptr<Light> make_light(const std::string& type, const ParamList& params,
                                  const Transform& to_world) {
    const SourceLocation at = params.where;
    std::unique_ptr<Light> light;
    if (type == "point") {
        Properties props("emitter", "point", at);
        props.set("intensity", emission(params, "I"), at);
        props.set("position", position(to_world, params, "from", Vec3(0.0f)), at);
        light = render::make_light(props, nullptr, {});
    } else if (type == "spot") {
        const Vec3 from = position(to_world, params, "from", Vec3(0.0f));
        const Vec3 to = position(to_world, params, "to", Vec3(0, 0, 1));
        const Vec3 d = to - from;
        if (!(length(d) > 0)) throw params.error("to", "\"from\" and \"to\" must differ");
        const Vec3 dir = normalize(d);
        const Vec3 up = std::abs(dir.y) < 0.9f ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
        const double cone = params.get_float("coneangle", 30.0);
        const double delta = params.get_float("conedelta", 5.0);
        if (!(cone > 0 && cone <= 180)) throw params.error("coneangle", "must be in (0, 180]");
        if (!(delta >= 0)) throw params.error("conedelta", "must be non-negative");
        Properties props("emitter", "spot", at);
        props.set("intensity", emission(params, "I"), at);
        props.set("to_world", Transform::look_at(from, from + dir, up), at);
        props.set("cutoff_angle", float(cone), at);
        props.set("beam_width", float(std::max(0.0, cone - delta)), at);
        if (delta > 0)
            warn(at, params.context() +
                         ": the falloff between coneangle - conedelta and coneangle is linear "
                         "in the angle (Mitsuba's), not pbrt's smoothstep in the cosine");
        light = render::make_light(props, nullptr, {});
    } else if (type == "distant") {
        if (params.has("illuminance"))
            throw params.error("illuminance", "not supported yet (give L and scale)");
        const Vec3 from = params.get_point3("from", Vec3(0.0f));
        const Vec3 to = params.get_point3("to", Vec3(0, 0, 1));
        const Vec3 d = to_world.apply_vector(to - from);
        if (!(length(d) > 0) || !is_finite(d))
            throw params.error("to", "\"from\" and \"to\" must differ");
        Properties props("emitter", "directional", at);
        props.set("direction", d, at);
        props.set("irradiance", emission(params, "L"), at);
        light = render::make_light(props, nullptr, {});
    } else if (type == "infinite") {
        if (params.has("filename"))
            throw params.error("filename",
                               "image infinite lights are not supported yet (pbrt-v4 stores "
                               "them as equal-area octahedral maps; ours are lat-long)");
        if (params.has("illuminance"))
            throw params.error("illuminance", "not supported yet (give L and scale)");
        if (params.has("portal")) throw params.error("portal", "portals are not supported yet");
        Properties props("emitter", "constant", at);
        props.set("radiance", emission(params, "L"), at);
        light = render::make_light(props, nullptr, {});
    } else if (type == "goniometric" || type == "projection") {
        throw SceneError(at, params.context() + ": light \"" + type + "\" is not supported yet");
    } else {
        throw SceneError(at, params.context() + ": unknown light \"" + type + "\"");
    }
    params.check_all_used();
    return light;
}

std::unique_ptr<Light> make_area_light(const std::string& type, const ParamList& params,
                                       const Shape* shape) {
    if (type != "diffuse")
        throw SceneError(params.where, params.context() + ": unknown area light \"" + type +
                                           "\" (supported: diffuse)");
    if (params.get_bool("twosided", false))
        throw params.error("twosided", "two-sided area lights are not supported yet");
    if (params.has("filename"))
        throw params.error("filename", "image area lights are not supported yet");
    Properties props("emitter", "area", params.where);
    props.set("radiance", emission(params, "L"), params.where);
    std::unique_ptr<Light> light = render::make_light(props, shape, {});
    params.check_all_used();
    return light;
}

}  // namespace render::pbrt
