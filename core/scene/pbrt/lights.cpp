// pbrt-v4 lights as the emitters of the Mitsuba loader (make_light). pbrt-v4 renders
// spectrally: an RGB emission becomes an illuminant spectrum (the colour's albedo spectrum
// times the colour space's D65), and every light divides its `scale` by that spectrum's
// photometric value so that RGB (1, 1, 1) is a 1-nit white, which pbrt's RGB film records as
// (1, 1, 1). An RGB renderer therefore emits the RGB value times `scale`, unchanged.

#include <algorithm>
#include <cmath>

#include "core/base/properties.h"
#include "core/image/exr_io.h"
#include "core/lights/envmap_light.h"
#include "core/lights/light_factory.h"
#include "core/math/constants.h"
#include "core/scene/pbrt/builders.h"
#include "core/textures/texture_factory.h"

namespace render::pbrt {
namespace {

// The emitted colour `name` times `scale` (pbrt's defaults: the colour space's white, 1).
Rgb emission(const ParamList& params, const char* name) {
    if (params.has("power"))
        throw params.error("power", "lights given by their power are not supported yet (use " +
                                        std::string(name) + " and scale)");
    Rgb colour(1.0f);
    if (params.type_of(name) == "blackbody") {
        const Param* p = params.find(name);
        if (p->numbers.size() != 1) throw params.error(name, "expects one temperature (kelvin)");
        p->used = true;
        const std::optional<Rgb> c = blackbody_rgb(p->numbers[0]);
        if (!c) throw params.error(name, "temperatures from 1667 to 25000 K are supported");
        colour = *c;
    } else {
        colour = get_rgb(params, name).value_or(Rgb(1.0f));
    }
    const double scale = params.get_float("scale", 1.0);
    if (!(scale >= 0)) throw params.error("scale", "must be non-negative");
    return colour * float(scale);
}

Vec3 position(const Transform& t, const ParamList& params, const char* name, const Vec3& def) {
    const Vec3 p = t.apply_point(params.get_point3(name, def));
    if (!is_finite(p)) throw params.error(name, "the transformed point is not finite");
    return p;
}

// pbrt-v4's equal-area octahedral mapping (Clarberg) of a unit direction to [0,1]^2.
Vec2 equal_area_sphere_to_square(const Vec3& d) {
    const double x = std::abs(d.x), y = std::abs(d.y), z = std::abs(d.z);
    const double r = std::sqrt(std::max(0.0, 1 - z));
    const double a = std::max(x, y), b = a == 0 ? 0 : std::min(x, y) / a;
    double phi = std::atan(b) * 2 / 3.14159265358979323846;
    if (x < y) phi = 1 - phi;
    double v = phi * r, u = r - v;
    if (d.z < 0) {
        std::swap(u, v);
        u = 1 - u;
        v = 1 - v;
    }
    u = std::copysign(u, double(d.x));
    v = std::copysign(v, double(d.y));
    return Vec2(float(0.5 * (u + 1)), float(0.5 * (v + 1)));
}

// Bilinear lookup of a square equal-area image at uv, texel centres at (i + 1/2) / n, rows top
// first (pbrt's Image::Bilerp); beyond an edge the octahedral map continues mirrored across
// that edge (pbrt's OctahedralSphere wrap).
Rgb octahedral_lookup(const Image& image, Vec2 uv) {
    const int n = image.width();
    auto texel = [&](int x, int y) {
        if (x < 0 || x >= n || y < 0 || y >= n) {
            if (x < 0) x = -x - 1, y = n - 1 - y;
            if (x >= n) x = 2 * n - 1 - x, y = n - 1 - y;
            if (y < 0) y = -y - 1, x = n - 1 - x;
            if (y >= n) y = 2 * n - 1 - y, x = n - 1 - x;
            x = std::clamp(x, 0, n - 1);
            y = std::clamp(y, 0, n - 1);
        }
        return image.at(x, y);
    };
    const float fx = uv.x * float(n) - 0.5f, fy = uv.y * float(n) - 0.5f;
    const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
    const float dx = fx - float(x0), dy = fy - float(y0);
    return texel(x0, y0) * ((1 - dx) * (1 - dy)) + texel(x0 + 1, y0) * (dx * (1 - dy)) +
           texel(x0, y0 + 1) * ((1 - dx) * dy) + texel(x0 + 1, y0 + 1) * (dx * dy);
}

// pbrt-v4's image infinite light: a square equal-area octahedral image in light space (the
// CTM), resampled onto our lat-long environment map (2n x n texels for an n x n image).
std::unique_ptr<Light> image_infinite(const ParamList& params, const Transform& to_world,
                                      const std::filesystem::path& file) {
    Image image(1, 1);
    try {
        image = read_image(file);
    } catch (const std::exception& e) {
        throw params.error("filename", e.what());
    }
    if (image.width() != image.height())
        throw params.error("filename",
                           "an image infinite light must be square (pbrt-v4's "
                           "equal-area octahedral map), not " +
                               std::to_string(image.width()) + " x " +
                               std::to_string(image.height()));
    const double scale = params.get_float("scale", 1.0);
    if (!(scale >= 0)) throw params.error("scale", "must be non-negative");
    if (!EnvmapLight::rotation_frame(to_world))
        throw params.error("filename", "the light's transform must be a rotation");
    const Transform to_light = to_world.inverse();
    const int n = image.width(), width = 2 * n, height = n;
    std::vector<Rgb> texels(size_t(width) * height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const Vec3 world = EnvmapLight::uv_to_direction(
                Vec2((float(x) + 0.5f) / float(width), (float(y) + 0.5f) / float(height)));
            const Vec3 light = normalize(to_light.apply_vector(world));
            const Rgb c = octahedral_lookup(image, equal_area_sphere_to_square(light));
            for (int k = 0; k < 3; ++k)
                if (!(std::isfinite(c[k]) && c[k] >= 0))
                    throw params.error("filename", "the image has negative or non-finite texels");
            texels[size_t(y) * width + x] = c * float(scale);
        }
    return std::make_unique<EnvmapLight>(std::move(texels), width, height, Frame(), file.string());
}

}  // namespace

std::unique_ptr<Light> make_light(
    const std::string& type, const ParamList& params, const Transform& to_world,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
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
        if (params.has("illuminance"))
            throw params.error("illuminance", "not supported yet (give L and scale)");
        if (params.has("portal")) throw params.error("portal", "portals are not supported yet");
        if (params.has("filename")) {
            if (params.has("L")) throw params.error("L", "give either \"L\" or \"filename\"");
            if (params.get_string("filename", "").empty())
                throw params.error("filename", "empty file name");
            light = image_infinite(params, to_world, resolve(params, "filename"));
            params.check_all_used();
            return light;
        }
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

std::unique_ptr<Light> make_area_light(
    const std::string& type, const ParamList& params, const Shape* shape,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
    if (type != "diffuse")
        throw SceneError(params.where, params.context() + ": unknown area light \"" + type +
                                           "\" (supported: diffuse)");
    if (params.get_bool("twosided", false))
        throw params.error("twosided", "two-sided area lights are not supported yet");
    Properties props("emitter", "area", params.where);
    if (params.has("filename")) {
        // pbrt-v4: L = scale x the image's RGB (bilinear, clamped) at (u, 1 - v) of pbrt's uv,
        // which is our uv (as for normal maps); our bitmap decodes 8-bit images as sRGB and reads
        // float ones linearly, as pbrt reads PNG and EXR.
        const SourceLocation at = params.find("filename")->where;
        if (params.get_string("filename", "").empty())
            throw params.error("filename", "a file name is required");
        if (params.has("L")) throw params.error("L", "give either \"L\" or \"filename\", not both");
        if (params.has("power"))
            throw params.error("power", "lights given by their power are not supported yet");
        if (params.get_float("scale", 1.0) != 1.0)
            throw params.error("scale", "a scaled image area light is not supported yet");
        Properties texture("texture", "bitmap", at);
        texture.set("filename", std::filesystem::absolute(resolve(params, "filename")).string(),
                    at);
        texture.set("wrap_mode", std::string("clamp"), at);  // pbrt's Bilerp default
        props.set("radiance", render::make_texture(texture), at);
        texture.check_all_used();
    } else {
        props.set("radiance", emission(params, "L"), params.where);
    }
    std::unique_ptr<Light> light = render::make_light(props, shape, {});
    params.check_all_used();
    return light;
}

}  // namespace render::pbrt
