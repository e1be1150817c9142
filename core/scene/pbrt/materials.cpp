// pbrt-v4 materials as the BSDFs of the Mitsuba loader (make_bsdf). docs/reference/scene-format.md,
// "pbrt-v4 scenes", lists each mapping and where our image differs from pbrt's.

#include <algorithm>
#include <cmath>
#include <iostream>

#include "core/base/properties.h"
#include "core/materials/bsdf_factory.h"
#include "core/materials/hair.h"
#include "core/materials/ior.h"
#include "core/math/constants.h"
#include "core/scene/pbrt/builders.h"
#include "core/textures/texture_factory.h"

namespace render::pbrt {
namespace {

// pbrt-v4 treats a microfacet distribution with alphas below this as a perfect specular one.
constexpr double kSmoothAlpha = 1e-3;

// Reflectance-like parameter `name` (rgb, grey float, constant spectrum or a texture) given to
// the Mitsuba parameter `to`. False when absent.
bool put_color(const ParamList& params, const std::string& name, Properties& props,
               const std::string& to, const TextureTable& textures) {
    if (!params.has(name)) return false;
    const SourceLocation where = params.find(name)->where;
    if (params.type_of(name) == "texture") {
        const Param* p = params.find(name);
        p->used = true;
        if (p->strings.size() != 1) throw params.error(name, "expects one texture name");
        auto it = textures.spectrum.find(p->strings[0]);
        if (it == textures.spectrum.end()) {
            it = textures.floats.find(p->strings[0]);
            if (it == textures.floats.end())
                throw params.error(name, "unknown texture \"" + p->strings[0] +
                                             "\" (a texture must be defined before it is used)");
        }
        props.set(to, it->second, where);
        return true;
    }
    props.set(to, *get_rgb(params, name), where);
    return true;
}

struct Alphas {
    double u = 0, v = 0;
    bool smooth() const { return std::max(u, v) < kSmoothAlpha; }
};

// roughness / uroughness / vroughness and remaproughness (pbrt-v4: alpha = sqrt(roughness)).
Alphas read_roughness(const ParamList& params, double def) {
    for (const char* n : {"roughness", "uroughness", "vroughness"})
        if (params.type_of(n) == "texture")
            throw params.error(n, "textured roughness is not supported yet for pbrt materials");
    const double r = params.get_float("roughness", def);
    double u = params.get_float("uroughness", r), v = params.get_float("vroughness", r);
    for (const char* n : {"roughness", "uroughness", "vroughness"})
        if (params.has(n) && !(params.get_float(n, 0) >= 0))
            throw params.error(n, "must be non-negative");
    if (params.get_bool("remaproughness", true)) {
        u = std::sqrt(u);
        v = std::sqrt(v);
    }
    return {u, v};
}

void put_alphas(Properties& props, const Alphas& a, const SourceLocation& where) {
    props.set("distribution", std::string("ggx"), where);  // pbrt's Trowbridge-Reitz
    props.set("alpha_u", float(a.u), where);
    props.set("alpha_v", float(a.v), where);
}

// A float `eta`; a named or varying spectrum (dispersion) is refused.
float read_eta(const ParamList& params, double def) {
    if (const Param* p = params.find("eta");
        p && p->type == "spectrum" && p->strings.size() == 1 && p->strings[0] == "glass-BK7") {
        // pbrt's dispersive BK7; we render without dispersion at BK7's index at 589 nm.
        p->used = true;
        warn(p->where,
             params.context() + ": \"glass-BK7\" is rendered without dispersion (index 1.5046)");
        return *lookup_dielectric_ior("bk7");
    }
    if (params.type_of("eta") == "spectrum") {
        if (std::optional<Rgb> c = get_rgb(params, "eta")) return c->r;
    }
    if (params.type_of("eta") == "texture")
        throw params.error("eta", "a textured index of refraction is not supported");
    const double eta = params.get_float("eta", def);
    if (!(eta > 0)) throw params.error("eta", "must be positive");
    return float(eta);
}

// pbrt-v4's named metal spectra ("metal-Ag-eta", "metal-Ag-k") that our RGB table has.
std::string metal_of(const ParamList& params, const std::string& name, const char* suffix) {
    const Param* p = params.find(name);
    if (!p || p->type != "spectrum" || p->strings.size() != 1) return "";
    const std::string& s = p->strings[0];
    const std::string head = "metal-", tail = std::string("-") + suffix;
    if (s.size() > head.size() + tail.size() && s.rfind(head, 0) == 0 &&
        s.compare(s.size() - tail.size(), tail.size(), tail) == 0) {
        const std::string metal = s.substr(head.size(), s.size() - head.size() - tail.size());
        if (metal == "Au" || metal == "Ag" || metal == "Cu" || metal == "Al" || metal == "Cr") {
            p->used = true;
            return metal;
        }
    }
    throw params.error(name, "the spectrum \"" + s +
                                 "\" is not supported (named metals: metal-Au, metal-Ag, "
                                 "metal-Cu, metal-Al, metal-Cr with -eta and -k)");
}

std::shared_ptr<const Bsdf> conductor(const ParamList& params, const SourceLocation& at) {
    const Alphas a = read_roughness(params, 0.0);
    Properties props("bsdf", a.smooth() ? "conductor" : "roughconductor", at);
    if (params.has("reflectance")) {
        if (params.has("eta") || params.has("k"))
            throw params.error("reflectance", "give either \"reflectance\" or \"eta\" and \"k\"");
        if (params.type_of("reflectance") == "texture")
            throw params.error("reflectance", "a textured conductor reflectance is not supported");
        // pbrt-v4's artist-friendly conductor: eta 1 and k = 2 sqrt(r) / sqrt(1 - r), whose
        // normal-incidence Fresnel reflectance is r.
        const Rgb r = *get_rgb(params, "reflectance");
        Rgb k;
        for (int c = 0; c < 3; ++c) {
            if (!(r[c] >= 0 && r[c] <= 1)) throw params.error("reflectance", "must be in [0, 1]");
            const float rc = std::min(r[c], 0.9999f);
            k[c] = 2 * std::sqrt(rc) / std::sqrt(1 - rc);
        }
        props.set("eta", Rgb(1.0f), params.find("reflectance")->where);
        props.set("k", k, params.find("reflectance")->where);
    } else {
        // pbrt-v4's default conductor is copper.
        const std::string eta_metal = metal_of(params, "eta", "eta");
        const std::string k_metal = metal_of(params, "k", "k");
        if (!eta_metal.empty() || !k_metal.empty() || (!params.has("eta") && !params.has("k"))) {
            const std::string metal =
                eta_metal.empty() ? (k_metal.empty() ? "Cu" : k_metal) : eta_metal;
            if ((!eta_metal.empty() && eta_metal != metal) ||
                (!k_metal.empty() && k_metal != metal) ||
                (params.has("eta") && eta_metal.empty()) || (params.has("k") && k_metal.empty()))
                throw params.error("k", "\"eta\" and \"k\" must name the same metal");
            props.set("material", metal, at);
        } else {
            if (!params.has("eta") || !params.has("k"))
                throw params.error(params.has("eta") ? "eta" : "k",
                                   "give both \"eta\" and \"k\" as rgb (or named metals)");
            put_color(params, "eta", props, "eta", {});
            put_color(params, "k", props, "k", {});
        }
    }
    if (!a.smooth()) put_alphas(props, a, at);
    return make_bsdf(props);
}

std::shared_ptr<const Bsdf> dielectric(const ParamList& params, const SourceLocation& at,
                                       bool thin) {
    const float eta = read_eta(params, 1.5);
    const Alphas a = thin ? Alphas{} : read_roughness(params, 0.0);
    Properties props("bsdf",
                     thin         ? "thindielectric"
                     : a.smooth() ? "dielectric"
                                  : "roughdielectric",
                     at);
    props.set("int_ior", eta, at);
    props.set("ext_ior", 1.0f, at);
    if (!thin && !a.smooth()) put_alphas(props, a, at);
    return make_bsdf(props);
}

std::shared_ptr<const Bsdf> coated_diffuse(const ParamList& params, const SourceLocation& at,
                                           const TextureTable& textures) {
    // A smooth coating is Mitsuba's `plastic`, a rough one `roughplastic` with pbrt's
    // Trowbridge-Reitz (GGX) distribution; both isotropic.
    const Alphas a = read_roughness(params, 0.0);
    Properties props("bsdf", a.smooth() ? "plastic" : "roughplastic", at);
    if (!put_color(params, "reflectance", props, "diffuse_reflectance", textures))
        props.set("diffuse_reflectance", Rgb(0.5f), at);
    props.set("int_ior", read_eta(params, 1.5), at);
    props.set("ext_ior", 1.0f, at);
    props.set("nonlinear", true, at);
    if (!a.smooth()) {
        double alpha = a.u;
        if (a.u != a.v) {
            alpha = 0.5 * (a.u + a.v);
            warn(params.where, params.context() + ": an anisotropic coating (alpha " +
                                   std::to_string(a.u) + ", " + std::to_string(a.v) +
                                   ") is rendered isotropic with their mean " +
                                   std::to_string(alpha));
        }
        props.set("distribution", std::string("ggx"), at);
        props.set("alpha", float(alpha), at);
    }
    // pbrt's stochastic layer evaluation: no effect on the mean of our analytic plastic.
    params.get_float("thickness", 0.01);
    params.get_int("maxdepth", 10);
    params.get_int("nsamples", 1);
    params.get_float("g", 0.0);
    if (std::optional<Rgb> albedo = get_rgb(params, "albedo"); albedo && albedo->max() > 0)
        throw params.error("albedo", "a scattering medium in the coating is not supported");
    return make_bsdf(props);
}

// pbrt's reflective BxDFs act on both sides of a surface (they work in whichever hemisphere wo
// is); ours are one-sided unless wrapped in `twosided`.
std::shared_ptr<const Bsdf> two_sided(std::shared_ptr<const Bsdf> bsdf, const SourceLocation& at) {
    Properties props("bsdf", "twosided", at);
    props.nested_bsdfs.push_back(std::move(bsdf));
    return make_bsdf(props);
}

// pbrt-v4's "string normalmap": an image (read linearly, bilinear, repeated, looked up at
// (u, 1 - t), which is our uv) whose 2 rgb - 1 is the normal in the tangent frame along dp/du:
// Mitsuba's normalmap with a raw bitmap, around the whole material.
std::shared_ptr<const Bsdf> normal_mapped(
    std::shared_ptr<const Bsdf> bsdf, const ParamList& params,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
    const SourceLocation at = params.find("normalmap")->where;
    if (params.get_string("normalmap", "").empty())
        throw params.error("normalmap", "a file name is required");
    Properties texture("texture", "bitmap", at);
    texture.set("filename", std::filesystem::absolute(resolve(params, "normalmap")).string(), at);
    texture.set("raw", true, at);
    Properties props("bsdf", "normalmap", at);
    props.set("normalmap", render::make_texture(texture), at);
    texture.check_all_used();
    props.nested_bsdfs.push_back(std::move(bsdf));
    return make_bsdf(props);
}

// pbrt-v4's "texture displacement": a float texture, the height in scene units along the
// shading normal. Mitsuba's bumpmap with scale 1 around the whole material (see
// docs/reference/scene-format.md for what differs from pbrt's BumpMap).
std::shared_ptr<const Bsdf> bump_mapped(std::shared_ptr<const Bsdf> bsdf, const ParamList& params,
                                        const TextureTable& textures) {
    const Param* p = params.find("displacement");
    p->used = true;
    if (params.type_of("displacement") != "texture")
        throw params.error("displacement", "expects \"texture displacement\" (a float texture)");
    if (p->strings.size() != 1) throw params.error("displacement", "expects one texture name");
    if (params.has("normalmap"))
        throw params.error("displacement",
                           "a normalmap and a displacement together are not supported (pbrt-v4 "
                           "would ignore the displacement)");
    auto it = textures.floats.find(p->strings[0]);
    if (it == textures.floats.end())
        throw params.error("displacement", "unknown float texture \"" + p->strings[0] +
                                               "\" (a texture must be defined before it is used)");
    Properties props("bsdf", "bumpmap", p->where);
    props.set("height", it->second, p->where);
    props.nested_bsdfs.push_back(std::move(bsdf));
    return make_bsdf(props);
}

// A hair parameter given as "texture NAME": the named texture (float or spectrum), or null.
std::shared_ptr<const Texture> hair_texture(const ParamList& params, const char* name,
                                            const TextureTable& textures) {
    if (params.type_of(name) != "texture") return nullptr;
    const Param* p = params.find(name);
    p->used = true;
    if (p->strings.size() != 1) throw params.error(name, "expects one texture name");
    for (const auto* table : {&textures.floats, &textures.spectrum})
        if (auto it = table->find(p->strings[0]); it != table->end()) return it->second;
    throw params.error(name, "unknown texture \"" + p->strings[0] +
                                 "\" (a texture must be defined before it is used)");
}

// pbrt-v4's hair (core/materials/hair.h), its parameters, defaults and h from the hit's v.
// Neither two-sided nor one-sided: the fibre model scatters over the whole sphere. Every
// parameter may be a texture, looked up at the hit's uv (HairTextures); a texture whose range
// leaves the parameter's is refused, as a constant would be.
std::shared_ptr<const Bsdf> hair(const ParamList& params, const TextureTable& textures) {
    HairTextures tex;
    tex.sigma_a = hair_texture(params, "sigma_a", textures);
    tex.reflectance = hair_texture(params, "reflectance", textures);
    tex.eumelanin = hair_texture(params, "eumelanin", textures);
    tex.pheomelanin = hair_texture(params, "pheomelanin", textures);
    tex.eta = hair_texture(params, "eta", textures);
    tex.beta_m = hair_texture(params, "beta_m", textures);
    tex.beta_n = hair_texture(params, "beta_n", textures);
    tex.alpha = hair_texture(params, "alpha", textures);
    const auto range = [&](const char* name, const std::shared_ptr<const Texture>& t, float lo,
                           float hi, const char* what) {
        if (t && !(t->min_value() >= lo && t->max_value() <= hi))
            throw params.error(name, std::string("the texture's values must ") + what);
    };
    range("eta", tex.eta, 1e-6f, kInfinity, "be positive");
    range("beta_m", tex.beta_m, 0, 1, "lie in [0, 1]");
    range("beta_n", tex.beta_n, 0, 1, "lie in [0, 1]");
    range("alpha", tex.alpha, -90, 90, "lie in [-90, 90] degrees");
    range("sigma_a", tex.sigma_a, 0, kInfinity, "be non-negative");
    range("reflectance", tex.reflectance, 1e-6f, 1, "lie in (0, 1]");
    range("eumelanin", tex.eumelanin, 0, kInfinity, "be non-negative");
    range("pheomelanin", tex.pheomelanin, 0, kInfinity, "be non-negative");
    // The constants (get_float of a textured parameter gives the default).
    const auto constant = [&](const char* name, double def) {
        return params.type_of(name) == "texture" ? def : params.get_float(name, def);
    };
    HairParams hair;
    hair.eta = float(constant("eta", 1.55));
    hair.beta_m = float(constant("beta_m", 0.3));
    hair.beta_n = float(constant("beta_n", 0.3));
    hair.alpha = float(constant("alpha", 2));
    if (!(hair.eta > 0)) throw params.error("eta", "must be positive");
    for (const char* name : {"beta_m", "beta_n"})
        if (!(constant(name, 0.3) >= 0 && constant(name, 0.3) <= 1))
            throw params.error(name, "must lie in [0, 1]");
    if (!(std::abs(hair.alpha) <= 90)) throw params.error("alpha", "must lie in [-90, 90] degrees");
    const bool melanin = params.has("eumelanin") || params.has("pheomelanin");
    if (int(params.has("sigma_a")) + int(params.has("reflectance")) + int(melanin) > 1)
        throw params.error(params.has("sigma_a") ? "sigma_a" : "reflectance",
                           "give one of sigma_a, reflectance or eumelanin/pheomelanin");
    if (params.has("sigma_a")) {
        tex.absorption = HairTextures::Absorption::SigmaA;
        if (!tex.sigma_a) {
            hair.sigma_a = *get_rgb(params, "sigma_a");
            if (!(std::min({hair.sigma_a.r, hair.sigma_a.g, hair.sigma_a.b}) >= 0))
                throw params.error("sigma_a", "must be non-negative");
        }
    } else if (params.has("reflectance")) {
        tex.absorption = HairTextures::Absorption::Reflectance;
        const Rgb c = tex.reflectance ? tex.reflectance->mean() : *get_rgb(params, "reflectance");
        if (!(std::min({c.r, c.g, c.b}) > 0 && std::max({c.r, c.g, c.b}) <= 1))
            throw params.error("reflectance", "must lie in (0, 1]");
        tex.reflectance_value = c;
        hair.sigma_a = HairBsdf::sigma_a_from_reflectance(c, hair.beta_n);
    } else {
        tex.absorption = HairTextures::Absorption::Melanin;
        // pbrt-v4: either concentration alone leaves the other at 0; neither is eumelanin 1.3.
        const double eu = constant("eumelanin", melanin ? 0.0 : 1.3),
                     pheo = constant("pheomelanin", 0.0);
        if (!(eu >= 0 && pheo >= 0))
            throw params.error(eu >= 0 ? "pheomelanin" : "eumelanin", "must be non-negative");
        tex.eumelanin_value = float(eu);
        tex.pheomelanin_value = float(pheo);
        hair.sigma_a = HairBsdf::sigma_a_from_concentration(float(eu), float(pheo));
    }
    return HairBsdf::pbrt_material(hair, tex);
}

}  // namespace

std::shared_ptr<const Bsdf> make_material(
    const std::string& type, const ParamList& params, const TextureTable& textures,
    const std::map<std::string, std::shared_ptr<const Bsdf>>& named,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
    const SourceLocation at = params.where;
    std::shared_ptr<const Bsdf> bsdf;
    if (type == "diffuse") {
        Properties props("bsdf", "diffuse", at);
        put_color(params, "reflectance", props, "reflectance", textures);
        bsdf = two_sided(make_bsdf(props), at);
    } else if (type == "diffusetransmission") {
        // Two-sided by itself: reflection on either side, transmission across.
        Properties props("bsdf", "diffusetransmission", at);
        put_color(params, "reflectance", props, "reflectance", textures);
        put_color(params, "transmittance", props, "transmittance", textures);
        if (params.has("scale")) props.set("scale", float(params.get_float("scale", 1)), at);
        bsdf = make_bsdf(props);
    } else if (type == "conductor") {
        bsdf = two_sided(conductor(params, at), at);
    } else if (type == "dielectric") {
        bsdf = dielectric(params, at, false);
    } else if (type == "thindielectric") {
        bsdf = dielectric(params, at, true);
    } else if (type == "coateddiffuse") {
        bsdf = two_sided(coated_diffuse(params, at, textures), at);
    } else if (type == "interface" || type == "") {
        Properties props("bsdf", "null", at);
        bsdf = make_bsdf(props);
    } else if (type == "mix") {
        // pbrt-v4 picks materials[1] with probability `amount` at each shading point; its
        // expectation is Mitsuba's blendbsdf with weight `amount` (0 and 1 pick one).
        const Param* m = params.find("materials");
        if (!m || m->type != "string" || m->strings.size() != 2)
            throw params.error("materials", "mix needs \"string materials\" with two names");
        m->used = true;
        std::shared_ptr<const Bsdf> pair[2];
        for (int i = 0; i < 2; ++i) {
            auto it = named.find(m->strings[size_t(i)]);
            if (it == named.end())
                throw params.error("materials",
                                   "unknown named material \"" + m->strings[size_t(i)] + "\"");
            pair[i] = it->second;
            if (pair[i]->changes_shading_frame())
                throw params.error("materials",
                                   "mixing \"" + m->strings[size_t(i)] +
                                       "\", a material with a normal or bump map, is not "
                                       "supported");
        }
        Properties props("bsdf", "blendbsdf", at);
        props.nested_bsdfs = {pair[0], pair[1]};
        if (params.type_of("amount") == "texture") {
            const Param* a = params.find("amount");
            a->used = true;
            if (a->strings.size() != 1) throw params.error("amount", "expects one texture name");
            auto it = textures.floats.find(a->strings[0]);
            if (it == textures.floats.end())
                throw params.error("amount",
                                   "unknown float texture \"" + a->strings[0] +
                                       "\" (a texture must be defined before it is used)");
            props.set("weight", it->second, a->where);
            bsdf = make_bsdf(props);
        } else {
            const double amount = params.get_float("amount", 0.5);
            if (amount <= 0 || amount >= 1) {
                bsdf = pair[amount <= 0 ? 0 : 1];
            } else {
                props.set("weight", float(amount), at);
                bsdf = make_bsdf(props);
            }
        }
    } else if (type == "hair") {
        bsdf = hair(params, textures);
    } else if (type == "coatedconductor" || type == "measured" || type == "subsurface") {
        throw SceneError(at, params.context() + ": material \"" + type + "\" is not supported yet");
    } else {
        throw SceneError(at, params.context() + ": unknown material \"" + type + "\"");
    }
    const bool surface = type != "mix" && type != "interface" && !type.empty();
    if (params.has("displacement") && surface) bsdf = bump_mapped(bsdf, params, textures);
    if (params.has("normalmap") && surface) bsdf = normal_mapped(bsdf, params, resolve);
    params.check_all_used();
    return bsdf;
}

}  // namespace render::pbrt
