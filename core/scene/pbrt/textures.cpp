// pbrt-v4 textures (imagemap, checkerboard, scale) as the Mitsuba loader's textures (bitmap,
// checkerboard, constant). pbrt's texture coordinates have v up; the loader stores mesh uv with
// v flipped (as the Mitsuba loader does), so each mapping's (uscale, vscale, udelta, vdelta)
// becomes a to_uv transform on the flipped coordinates.

#include "core/base/properties.h"
#include "core/scene/pbrt/builders.h"
#include "core/textures/constant_texture.h"
#include "core/textures/texture_factory.h"

namespace render::pbrt {
namespace {

struct UvMapping {
    double su = 1, sv = 1, du = 0, dv = 0;
};

UvMapping read_mapping(const ParamList& params) {
    const std::string mapping = params.get_string("mapping", "uv");
    if (mapping != "uv") throw params.error("mapping", "only the \"uv\" mapping is supported yet");
    return {params.get_float("uscale", 1), params.get_float("vscale", 1),
            params.get_float("udelta", 0), params.get_float("vdelta", 0)};
}

// (u, v) -> (a u + b, c v + d) as a to_uv transform.
Transform uv_affine(double a, double b, double c, double d) {
    Transform::Matrix m{};
    m[0][0] = a;
    m[0][3] = b;
    m[1][1] = c;
    m[1][3] = d;
    m[2][2] = 1;
    m[3][3] = 1;
    return Transform(m);
}

// A colour or float parameter of a texture that may also name another texture.
std::shared_ptr<const Texture> texture_or_value(const ParamList& params, const std::string& name,
                                                const Rgb& def, const TextureTable& textures) {
    if (params.type_of(name) == "texture") {
        const Param* p = params.find(name);
        p->used = true;
        auto s = textures.spectrum.find(p->strings[0]);
        if (s != textures.spectrum.end()) return s->second;
        auto f = textures.floats.find(p->strings[0]);
        if (f != textures.floats.end()) return f->second;
        throw params.error(name, "unknown texture \"" + p->strings[0] + "\"");
    }
    return std::make_shared<ConstantTexture>(get_rgb(params, name).value_or(def));
}

}  // namespace

std::shared_ptr<const Texture> make_texture(
    const std::string& texture_class, const ParamList& params, const TextureTable& textures,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
    const SourceLocation at = params.where;
    std::shared_ptr<const Texture> texture;
    if (texture_class == "imagemap") {
        const UvMapping m = read_mapping(params);
        Properties props("texture", "bitmap", at);
        if (params.get_string("filename", "").empty())
            throw params.error("filename", "a file name is required");
        props.set("filename", std::filesystem::absolute(resolve(params, "filename")).string(), at);
        const std::string filter = params.get_string("filter", "bilinear");
        if (filter == "point")
            props.set("filter_type", std::string("nearest"), at);
        else if (filter == "bilinear")
            props.set("filter_type", std::string("bilinear"), at);
        else if (filter == "trilinear" || filter == "ewa") {
            warn(params.find("filter")->where,
                 "imagemap filter \"" + filter + "\": bilinear lookups are used (no MIP maps)");
            props.set("filter_type", std::string("bilinear"), at);
        } else {
            throw params.error("filter", "unknown filter (point, bilinear, trilinear, ewa)");
        }
        const std::string wrap = params.get_string("wrap", "repeat");
        if (wrap != "repeat" && wrap != "clamp")
            throw params.error("wrap", "only \"repeat\" and \"clamp\" are supported yet");
        props.set("wrap_mode", wrap, at);
        const std::string encoding = params.get_string("encoding", "sRGB");
        if (encoding == "linear")
            props.set("raw", true, at);
        else if (encoding != "sRGB")
            throw params.error("encoding", "only \"sRGB\" and \"linear\" are supported yet");
        if (params.get_float("scale", 1.0) != 1.0)
            throw params.error("scale", "a scaled image texture is not supported yet");
        if (params.get_bool("invert", false))
            throw params.error("invert", "inverted image textures are not supported yet");
        props.set("to_uv", uv_affine(m.su, m.du, m.sv, 1 - m.sv - m.dv), at);
        texture = render::make_texture(props);
        props.check_all_used();
    } else if (texture_class == "checkerboard") {
        if (params.get_int("dimension", 2) != 2)
            throw params.error("dimension", "only 2-D checkerboards are supported yet");
        const UvMapping m = read_mapping(params);
        Properties props("texture", "checkerboard", at);
        props.set("color0", texture_or_value(params, "tex1", Rgb(1.0f), textures), at);
        props.set("color1", texture_or_value(params, "tex2", Rgb(0.0f), textures), at);
        // pbrt: tex1 where floor(s') + floor(t') is even; ours: color0 where the fractional
        // parts of u'' and v'' are on the same side of 1/2. u'' = s'/2, v'' = t'/2 with
        // s' = su u + du and t' = sv (1 - v) + dv (v is flipped).
        props.set("to_uv", uv_affine(m.su / 2, m.du / 2, -m.sv / 2, (m.sv + m.dv) / 2), at);
        texture = render::make_texture(props);
        props.check_all_used();
    } else if (texture_class == "scale") {
        const std::shared_ptr<const Texture> tex =
            texture_or_value(params, "tex", Rgb(1.0f), textures);
        if (params.type_of("scale") == "texture")
            throw params.error("scale", "a textured scale is not supported yet");
        const double s = params.get_float("scale", 1.0);
        if (params.type_of("tex") != "texture")
            texture = std::make_shared<ConstantTexture>(get_rgb(params, "tex").value_or(Rgb(1.0f)) *
                                                        float(s));
        else if (s == 1.0)
            texture = tex;
        else
            throw params.error("scale", "scaling a texture by other than 1 is not supported yet");
    } else if (texture_class == "constant") {
        texture = std::make_shared<ConstantTexture>(get_rgb(params, "value").value_or(Rgb(1.0f)));
    } else {
        throw SceneError(at, params.context() + ": texture \"" + texture_class +
                                 "\" is not supported yet (imagemap, checkerboard, scale, "
                                 "constant)");
    }
    params.check_all_used();
    return texture;
}

}  // namespace render::pbrt
