#include "core/materials/bsdf_params.h"

#include <cmath>
#include <sstream>

namespace render {
namespace {

std::string join(const std::vector<std::string>& names) {
    std::string result;
    for (size_t i = 0; i < names.size(); ++i) result += (i ? ", " : "") + names[i];
    return result;
}

std::string format(float value) {
    std::ostringstream out;
    out << value;
    return out.str();
}

bool is_valid_reflectance(const Rgb& c) {
    return c.is_finite() && c.r >= 0 && c.g >= 0 && c.b >= 0;
}

}  // namespace

Rgb read_reflectance(const Properties& props, const std::string& name, const Rgb& def) {
    const Rgb value = props.get_rgb(name, def);
    if (!is_valid_reflectance(value))
        throw props.error(name, "must be finite and non-negative (got " + format(value.r) + ", " +
                                    format(value.g) + ", " + format(value.b) + ")");
    return value;
}

float read_non_negative(const Properties& props, const std::string& name, float def) {
    const float value = props.get_float(name, def);
    if (!std::isfinite(value) || value < 0)
        throw props.error(name, "must be finite and non-negative (got " + format(value) + ")");
    return value;
}

float read_ior(const Properties& props, const std::string& name, float def) {
    if (!props.has(name)) return def;
    // Properties cannot tell the stored type, so try the number first, then the name.
    float value;
    try {
        value = props.get_float(name);
    } catch (const SceneError&) {
        const std::string ior_name = props.get_string(name);
        const std::optional<float> named = lookup_dielectric_ior(ior_name);
        if (!named)
            throw props.error(name, "unknown IOR name \"" + ior_name +
                                        "\" (known: " + join(dielectric_ior_names()) + ")");
        return *named;
    }
    if (!std::isfinite(value) || value <= 0)
        throw props.error(name,
                          "an index of refraction must be positive (got " + format(value) + ")");
    return value;
}

float read_relative_ior(const Properties& props, float int_default) {
    const float int_ior = read_ior(props, "int_ior", int_default);
    const float ext_ior = read_ior(props, "ext_ior", *lookup_dielectric_ior("air"));
    return int_ior / ext_ior;
}

MicrofacetParams read_microfacet_params(const Properties& props) {
    const std::string name = props.get_string("distribution", "beckmann");
    MicrofacetParams params;
    if (!parse_microfacet_type(name, params.type))
        throw props.error("distribution",
                          "unknown distribution \"" + name + "\" (supported: beckmann, ggx)");

    auto read_alpha = [&](const std::string& param, float def) {
        if (std::shared_ptr<const Texture> texture = props.get_texture(param)) {
            const float lo = texture->min_value(), hi = texture->max_value();
            if (!std::isfinite(lo) || !std::isfinite(hi) || lo < 0)
                throw props.error(param,
                                  "a roughness texture must be finite and non-negative "
                                  "(" +
                                      texture->to_string() + " reaches " + format(lo) + ")");
            return FloatParam{0.0f, texture};
        }
        const float alpha = props.get_float(param, def);
        if (!std::isfinite(alpha) || alpha < 0)
            throw props.error(
                param, "roughness must be finite and non-negative (got " + format(alpha) + ")");
        return FloatParam{alpha, nullptr};
    };
    if (props.has("alpha_u") || props.has("alpha_v")) {
        if (props.has("alpha"))
            throw props.error("alpha", "give either alpha or alpha_u/alpha_v, not both");
        if (!props.has("alpha_u") || !props.has("alpha_v"))
            throw props.error(props.has("alpha_u") ? "alpha_u" : "alpha_v",
                              "alpha_u and alpha_v must be given together");
        params.alpha_u = read_alpha("alpha_u", 0.1f);
        params.alpha_v = read_alpha("alpha_v", 0.1f);
    } else {
        params.alpha_u = read_alpha("alpha", 0.1f);
        params.isotropic = true;
    }
    params.sample_visible = props.get_bool("sample_visible", true);
    return params;
}

MicrofacetDistribution MicrofacetParams::at(Vec2 uv) const {
    const float au = alpha_u.at(uv);
    return MicrofacetDistribution(type, au, isotropic ? au : alpha_v.at(uv), sample_visible);
}

MicrofacetDistribution MicrofacetParams::mean() const {
    const float au = alpha_u.mean();
    return MicrofacetDistribution(type, au, isotropic ? au : alpha_v.mean(), sample_visible);
}

RgbParam read_reflectance_param(const Properties& props, const std::string& name, const Rgb& def) {
    if (std::shared_ptr<const Texture> texture = props.get_texture(name)) {
        const float lo = texture->min_value(), hi = texture->max_value();
        if (!std::isfinite(lo) || !std::isfinite(hi) || lo < 0)
            throw props.error(name, "a reflectance texture must be finite and non-negative (" +
                                        texture->to_string() + " reaches " + format(lo) + ")");
        return RgbParam{Rgb(), texture};
    }
    return RgbParam{read_reflectance(props, name, def), nullptr};
}

std::optional<ConductorIor> read_conductor_ior(const Properties& props) {
    if (props.has("eta") || props.has("k")) {
        if (props.has("material"))
            throw props.error("material", "give either eta/k or material, not both");
        // Mitsuba 3's defaults when only one of the two is given.
        ConductorIor ior{read_reflectance(props, "eta", Rgb(0.0f)),
                         read_reflectance(props, "k", Rgb(1.0f))};
        return ior;
    }
    const std::string material = props.get_string("material", "none");
    if (material == "none") return std::nullopt;
    std::optional<ConductorIor> ior = lookup_conductor_ior(material);
    if (!ior)
        throw props.error("material", "unknown conductor \"" + material + "\" (known: none, " +
                                          join(conductor_names()) + ")");
    return ior;
}

}  // namespace render
