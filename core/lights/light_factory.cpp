#include "core/lights/light_factory.h"

#include <cmath>
#include <sstream>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/base/plugin_table.h"
#include "core/base/scene_limits.h"
#include "core/lights/area_light.h"
#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/lights/envmap_light.h"
#include "core/lights/point_light.h"
#include "core/lights/spot_light.h"
#include "core/math/constants.h"
#include "core/textures/texture.h"

namespace render {
namespace {

// Emitted quantities must be finite and non-negative: a negative or NaN radiance would
// poison every image sample it touches.
Rgb get_emission(const Properties& props, const std::string& name, const Rgb& def) {
    Rgb value = props.get_rgb(name, def);
    for (int c = 0; c < 3; ++c)
        if (!std::isfinite(value[c]) || value[c] < 0) {
            std::ostringstream os;
            os << "must be finite and non-negative, got " << value;
            throw props.error(name, os.str());
        }
    return value;
}

// Every light's to_world is a transform rays start from: refused at its line when
// near-singular or not finite, as a shape's (Properties::get_ray_transform), after the
// light's position (a light placed too far is told so).
std::unique_ptr<Light> make_point(const Properties& props) {
    if (props.has("position") && props.has("to_world"))
        throw props.error("position", "give either \"position\" or \"to_world\", not both");
    Vec3 position = props.has("position")
                        ? props.get_vec3("position")
                        : props.get_transform("to_world", Transform()).apply_point(Vec3(0.0f));
    if (!within_scene_limits(position))
        throw props.error(props.has("position") ? "position" : "to_world",
                          "the position must be finite and within 1e12 of the origin");
    props.get_ray_transform("to_world");
    return std::make_unique<PointLight>(position, get_emission(props, "intensity", Rgb(1.0f)));
}

// Mitsuba's `spot`: at the origin of to_world, shining along its +z.
std::unique_ptr<Light> make_spot(const Properties& props) {
    const Transform to_world = props.get_transform("to_world", Transform());
    const Vec3 position = to_world.apply_point(Vec3(0.0f));
    if (!within_scene_limits(position))
        throw props.error("to_world", "the position must be finite and within 1e12 of the origin");
    props.get_ray_transform("to_world");
    std::optional<Frame> frame = EnvmapLight::rotation_frame(to_world);
    if (!frame)
        throw props.error("to_world",
                          "a spot light's to_world must be a rotation and translation (e.g. "
                          "<lookat>), optionally uniformly scaled");
    const float cutoff = props.get_float("cutoff_angle", 20.0f);
    if (!(cutoff > 0 && cutoff <= 180))
        throw props.error("cutoff_angle", "must be in (0, 180] degrees");
    const float beam = props.get_float("beam_width", cutoff * 0.75f);
    if (!(beam >= 0 && beam <= cutoff))
        throw props.error("beam_width", "must be in [0, cutoff_angle] degrees");
    // Mitsuba 3's projected texture; a constant `texture` has no effect in Mitsuba (it uses
    // only a spatially varying one), so it is read and ignored.
    std::shared_ptr<const Texture> texture = props.get_texture("texture");
    if (texture) {
        const float lo = texture->min_value(), hi = texture->max_value();
        if (!std::isfinite(lo) || !std::isfinite(hi) || lo < 0)
            throw props.error("texture", "the texture must be finite and non-negative (" +
                                             texture->to_string() + ")");
        if (!(cutoff < 90))
            throw props.error("texture",
                              "a projected texture needs cutoff_angle below 90 degrees (it "
                              "spans the cone's tangent plane)");
    } else if (props.has("texture")) {
        props.get_rgb("texture");
    }
    return std::make_unique<SpotLight>(
        position, *frame, get_emission(props, "intensity", Rgb(1.0f)), cutoff * kPi / 180.0f,
        beam * kPi / 180.0f, std::move(texture));
}

std::unique_ptr<Light> make_directional(const Properties& props) {
    if (props.has("direction") && props.has("to_world"))
        throw props.error("direction", "give either \"direction\" or \"to_world\", not both");
    // Mitsuba: the light travels along the local +z axis.
    const char* name = props.has("direction") ? "direction" : "to_world";
    Vec3 direction = props.has("direction")
                         ? props.get_vec3("direction")
                         : props.get_ray_transform("to_world").apply_vector(Vec3(0, 0, 1));
    float len = length(direction);
    if (!(len > 0) || !std::isfinite(len))
        throw props.error(name, "the light's direction must be a finite, non-zero vector");
    return std::make_unique<DirectionalLight>(direction,
                                              get_emission(props, "irradiance", Rgb(1.0f)));
}

std::unique_ptr<Light> make_envmap(const Properties& props,
                                   const std::filesystem::path& scene_dir) {
    std::filesystem::path filename = props.get_string("filename");
    if (filename.is_relative()) filename = scene_dir / filename;
    float scale = props.get_float("scale", 1.0f);
    if (!std::isfinite(scale) || scale < 0)
        throw props.error("scale", "must be finite and non-negative");
    std::optional<Frame> frame = EnvmapLight::rotation_frame(props.get_ray_transform("to_world"));
    if (!frame) throw props.error("to_world", "an environment map's to_world must be a rotation");
    try {
        return EnvmapLight::load(filename, scale, *frame);
    } catch (const SceneError& e) {
        rethrow_scene_error(e, props.error("filename", e.what()));
    }
}

std::unique_ptr<Light> make_area(const Properties& props, const Shape* shape,
                                 const std::filesystem::path&) {
    if (std::shared_ptr<const Texture> texture = props.get_texture("radiance")) {
        const float lo = texture->min_value(), hi = texture->max_value();
        if (!std::isfinite(lo) || !std::isfinite(hi) || lo < 0)
            throw props.error("radiance", "a radiance texture must be finite and non-negative (" +
                                              texture->to_string() + ")");
        try {
            // Ours, not Mitsuba's: uniform area sampling of a textured mesh, for comparisons.
            const bool uniform = props.get_bool("uniform_sampling", false);
            return std::make_unique<AreaLight>(shape, RgbParam{Rgb(), texture}, !uniform);
        } catch (const std::invalid_argument& e) {
            throw props.error("radiance", e.what() + std::string(", not ") +
                                              (shape ? shape->to_string() : "no shape"));
        }
    }
    return std::make_unique<AreaLight>(shape, get_emission(props, "radiance", Rgb(1.0f)));
}

std::unique_ptr<Light> make_constant(const Properties& props, const Shape*,
                                     const std::filesystem::path&) {
    return std::make_unique<ConstantLight>(get_emission(props, "radiance", Rgb(1.0f)));
}

// The registry: scene-file name -> factory. Only "area" is nested in a shape (it emits from
// its surface); every other emitter stands alone.
using LightFactory = std::unique_ptr<Light> (*)(const Properties&, const Shape*,
                                                const std::filesystem::path&);
const Plugin<LightFactory> kPlugins[] = {
    {"area", make_area},
    {"point",
     [](const Properties& p, const Shape*, const std::filesystem::path&) { return make_point(p); }},
    {"spot",
     [](const Properties& p, const Shape*, const std::filesystem::path&) { return make_spot(p); }},
    {"directional", [](const Properties& p, const Shape*,
                       const std::filesystem::path&) { return make_directional(p); }},
    {"constant", make_constant},
    {"envmap", [](const Properties& p, const Shape*,
                  const std::filesystem::path& dir) { return make_envmap(p, dir); }},
};

}  // namespace

std::unique_ptr<Light> make_light(const Properties& props, const Shape* shape,
                                  const std::filesystem::path& scene_dir) {
    const auto& plugin = find_plugin(kPlugins, props, "emitter");
    const bool on_shape = props.type() == "area";
    if (on_shape && !shape)
        throw SceneError(props.where(),
                         "emitter \"area\" must be nested inside a shape (it emits "
                         "from that shape's surface)");
    if (!on_shape && shape)
        throw SceneError(props.where(), "emitter \"" + props.type() +
                                            "\" cannot be nested inside a shape (only \"area\" "
                                            "can)");
    return plugin.create(props, shape, scene_dir);
}

}  // namespace render
