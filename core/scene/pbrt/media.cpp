// pbrt-v4 media (homogeneous, uniformgrid) as the Mitsuba loader's media (homogeneous with
// sigmaA/sigmaS, heterogeneous with a grid volume), through make_medium.
// docs/reference/scene-format.md, "pbrt-v4 scenes".

#include <cmath>

#include "core/base/properties.h"
#include "core/base/ray_transform_check.h"
#include "core/base/scene_limits.h"
#include "core/media/grid_volume.h"
#include "core/media/medium_factory.h"
#include "core/scene/pbrt/builders.h"

namespace render::pbrt {
namespace {

Rgb coefficient(const ParamList& params, const char* name) {
    const Rgb v = get_rgb(params, name).value_or(Rgb(1.0f));  // pbrt-v4's default: 1
    for (int c = 0; c < 3; ++c)
        if (!(v[c] >= 0)) throw params.error(name, "must be non-negative");
    return v;
}

std::shared_ptr<const PhaseFunction> phase(const ParamList& params) {
    const double g = params.get_float("g", 0.0);
    if (!(g > -1 && g < 1)) throw params.error("g", "must be in (-1, 1)");
    Properties props("phase", g == 0 ? "isotropic" : "hg", params.where);
    if (g != 0) props.set("g", float(g), params.where);
    return make_phase(props);
}

void refuse_unsupported(const ParamList& params) {
    for (const char* name :
         {"temperature", "temperaturescale", "temperaturecutoff", "temperatureoffset"})
        if (params.has(name))
            throw params.error(name,
                               "emission by temperature grids is not supported yet (give "
                               "Le and Lescale)");
    if (params.has("preset"))
        throw params.error("preset",
                           "named measured media are not supported yet (give "
                           "sigma_a and sigma_s)");
}

// pbrt-v4's emitted radiance Le (an illuminant spectrum: an RGB, or a blackbody temperature),
// without Lescale; black when absent. As for lights (lights.cpp), pbrt divides the scale by
// the spectrum's photometric value, so an RGB renderer emits the RGB value itself and a
// blackbody its unit-luminance colour. The source term is sigma_a Le in both renderers.
Rgb emitted_radiance(const ParamList& params) {
    if (!params.has("Le")) return Rgb(0.0f);
    if (params.type_of("Le") == "blackbody") {
        const Param* p = params.find("Le");
        if (p->numbers.size() != 1) throw params.error("Le", "expects one temperature (kelvin)");
        p->used = true;
        const std::optional<Rgb> c = blackbody_rgb(p->numbers[0]);
        if (!c) throw params.error("Le", "temperatures from 1667 to 25000 K are supported");
        return *c;
    }
    const Rgb le = *get_rgb(params, "Le");
    for (int c = 0; c < 3; ++c)
        if (!(le[c] >= 0 && std::isfinite(le[c])))
            throw params.error("Le", "must be finite and non-negative");
    return le;
}

}  // namespace

std::shared_ptr<const Medium> make_medium(const std::string& type, const ParamList& params,
                                          const Transform& to_world) {
    const SourceLocation at = params.where;
    refuse_unsupported(params);
    const Rgb le = emitted_radiance(params);
    const Rgb sigma_a = coefficient(params, "sigma_a"), sigma_s = coefficient(params, "sigma_s");
    const double scale = params.get_float("scale", 1.0);
    if (!(scale >= 0)) throw params.error("scale", "must be non-negative");
    std::shared_ptr<const Medium> medium;
    if (type == "homogeneous") {
        Properties props("medium", "homogeneous", at);
        props.set("sigmaA", sigma_a, at);
        props.set("sigmaS", sigma_s, at);
        props.set("scale", float(scale), at);
        const double le_scale = params.get_float("Lescale", 1.0);
        if (!(le_scale >= 0 && std::isfinite(le_scale)))
            throw params.error("Lescale", "must be finite and non-negative");
        props.set("radiance", le * float(le_scale), at);
        medium = render::make_medium(props, phase(params), {});
    } else if (type == "uniformgrid") {
        const long long nx = params.get_int("nx", 1), ny = params.get_int("ny", 1),
                        nz = params.get_int("nz", 1);
        if (nx < 1 || ny < 1 || nz < 1 || nx * ny > (1ll << 31) / nz)
            throw params.error("nx", "the grid size must be positive (and below 2^31 voxels)");
        const std::vector<double> density = params.get_numbers("density", {"float"}, 1);
        if (density.size() != size_t(nx * ny * nz))
            throw params.error("density", "expects nx * ny * nz = " + std::to_string(nx * ny * nz) +
                                              " values, got " + std::to_string(density.size()));
        const Vec3 p0 = params.get_point3("p0", Vec3(0.0f)),
                   p1 = params.get_point3("p1", Vec3(1.0f));
        if (!(p1.x > p0.x && p1.y > p0.y && p1.z > p0.z))
            throw params.error("p1", "must be above p0 on every axis");
        // sigma_t(p) = scale (sigma_a + sigma_s) density(p), albedo sigma_s / sigma_t: an RGB
        // extinction grid and a constant albedo.
        const Rgb sigma_t = sigma_a + sigma_s;
        VolumeGridData data;
        data.xres = int(nx), data.yres = int(ny), data.zres = int(nz), data.channels = 3;
        data.bbox.expand(p0);
        data.bbox.expand(p1);
        data.values.reserve(density.size() * 3);
        for (double d : density) {
            if (!(d >= 0)) throw params.error("density", "values must be non-negative");
            for (int c = 0; c < 3; ++c) data.values.push_back(float(d) * sigma_t[c]);
        }
        Rgb albedo;
        for (int c = 0; c < 3; ++c) albedo[c] = sigma_t[c] > 0 ? sigma_s[c] / sigma_t[c] : 0.0f;
        if (const std::string problem = ray_transform_problem(to_world); !problem.empty())
            throw SceneError(at, params.context() + ": " + problem);
        const Transform grid_to_world =
            to_world * Transform::translate(p0) * Transform::scale(p1 - p0);
        std::map<std::string, std::shared_ptr<const Volume>> volumes;
        volumes["sigma_t"] = std::make_shared<GridVolume>(
            std::move(data), grid_to_world, VolumeFilter::kTrilinear, params.context());
        // Emission: Le times Lescale, which is one float or a grid of nx * ny * nz floats on
        // the density's lattice (pbrt-v4's GridMedium; not multiplied by the density, whose
        // sigma_a already is). Ours: an RGB radiance grid, or a constant.
        if (params.has("Lescale") && params.find("Lescale")->numbers.size() > 1) {
            const std::vector<double> le_scale = params.get_numbers("Lescale", {"float"}, 1);
            if (le_scale.size() != size_t(nx * ny * nz))
                throw params.error("Lescale",
                                   "expects 1 or nx * ny * nz = " + std::to_string(nx * ny * nz) +
                                       " values, got " + std::to_string(le_scale.size()));
            VolumeGridData emission;
            emission.xres = int(nx), emission.yres = int(ny), emission.zres = int(nz);
            emission.channels = 3;
            emission.bbox.expand(p0);
            emission.bbox.expand(p1);
            emission.values.reserve(le_scale.size() * 3);
            for (double v : le_scale) {
                if (!(v >= 0 && std::isfinite(v)))
                    throw params.error("Lescale", "values must be finite and non-negative");
                for (int c = 0; c < 3; ++c) emission.values.push_back(float(v) * le[c]);
            }
            volumes["radiance"] = std::make_shared<GridVolume>(
                std::move(emission), grid_to_world, VolumeFilter::kTrilinear, params.context());
        }
        Properties props("medium", "heterogeneous", at);
        if (!volumes.count("radiance")) {
            const double le_scale = params.get_float("Lescale", 1.0);
            if (!(le_scale >= 0 && std::isfinite(le_scale)))
                throw params.error("Lescale", "must be finite and non-negative");
            if (le.max() > 0) props.set("radiance", le * float(le_scale), at);
        }
        props.set("albedo", albedo, at);
        props.set("scale", float(scale), at);
        medium = render::make_medium(props, phase(params), volumes);
    } else if (type == "cloud" || type == "nanovdb" || type == "rgbgrid") {
        throw SceneError(at, params.context() + ": medium \"" + type + "\" is not supported yet");
    } else {
        throw SceneError(at, params.context() + ": unknown medium \"" + type + "\"");
    }
    params.check_all_used();
    return medium;
}

}  // namespace render::pbrt
