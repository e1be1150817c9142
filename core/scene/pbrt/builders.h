#pragma once

// pbrt-v4 plugins (materials, shapes, lights, textures) mapped onto the objects the Mitsuba
// loader builds: each function fills a Mitsuba-style Properties and calls the same factory
// (make_bsdf, make_shape, make_light, make_texture), or builds the same shape class. What is
// mapped how is documented in docs/reference/scene-format.md, "pbrt-v4 scenes".

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "core/base/shape.h"
#include "core/lights/light.h"
#include "core/materials/bsdf.h"
#include "core/math/transform.h"
#include "core/media/medium.h"
#include "core/scene/pbrt/parameters.h"
#include "core/textures/texture.h"

namespace render::pbrt {

// Named textures of the file (pbrt has separate float and spectrum namespaces).
struct TextureTable {
    std::map<std::string, std::shared_ptr<const Texture>> spectrum;
    std::map<std::string, std::shared_ptr<const Texture>> floats;
};

// Prints "warning: file:line: message" (a feature read but without effect on our image).
void warn(const SourceLocation& where, const std::string& message);

// An RGB value of a colour parameter (`rgb`, a grey `float`, or a `spectrum` whose values are
// all equal); nothing when absent. Other spectra (named, varying, blackbody) are refused.
std::optional<Rgb> get_rgb(const ParamList& params, const std::string& name);

// The linear sRGB colour of a blackbody at `kelvin` with luminance 1 (pbrt-v4 normalises a
// blackbody light to unit luminance), negative components clamped to 0; nothing outside
// [1667, 25000] K, where the chromaticity approximation holds.
std::optional<Rgb> blackbody_rgb(double kelvin);

// `Material "type"` / MakeNamedMaterial's "string type". `named` resolves `mix`'s materials;
// `resolve` a "string normalmap" file name.
std::shared_ptr<const Bsdf> make_material(
    const std::string& type, const ParamList& params, const TextureTable& textures,
    const std::map<std::string, std::shared_ptr<const Bsdf>>& named,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve);

// `Shape "type"` with the current transform: one shape, or two for a plymesh of triangles and
// non-planar quads (a TriangleMesh and BilinearPatches). `resolve` maps a file name to the file
// to open.
std::vector<std::unique_ptr<Shape>> make_shapes(
    const std::string& type, const ParamList& params, const Transform& object_to_world,
    bool reverse_orientation,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve);

// `LightSource "type"` with the current transform; `resolve` as for shapes (image lights).
std::unique_ptr<Light> make_light(
    const std::string& type, const ParamList& params, const Transform& light_to_world,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve);

// `AreaLightSource "diffuse"` on `shape`; `resolve` its image ("string filename").
std::unique_ptr<Light> make_area_light(
    const std::string& type, const ParamList& params, const Shape* shape,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve);

// `MakeNamedMedium` of "string type" homogeneous or uniformgrid, with the current transform.
std::shared_ptr<const Medium> make_medium(const std::string& type, const ParamList& params,
                                          const Transform& medium_to_world);

// `Texture "name" "spectrum"|"float" "class"`.
std::shared_ptr<const Texture> make_texture(
    const std::string& texture_class, const ParamList& params, const TextureTable& textures,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve);

}  // namespace render::pbrt
