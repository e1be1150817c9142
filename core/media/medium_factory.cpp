#include "core/media/medium_factory.h"

#include "core/base/plugin_table.h"

#include <cmath>

#include "core/media/constant_volume.h"
#include "core/media/henyey_greenstein.h"
#include "core/media/heterogeneous_medium_factory.h"
#include "core/media/homogeneous_medium.h"
#include "core/media/isotropic_phase.h"

namespace render {
namespace {

bool valid_coefficient(const Rgb& c) {
    return c.is_finite() && c.r >= 0 && c.g >= 0 && c.b >= 0;
}

std::shared_ptr<const Medium> make_homogeneous(const Properties& props,
                                               std::shared_ptr<const PhaseFunction> phase) {
    const float scale = props.get_float("scale", 1.0f);
    if (!(std::isfinite(scale) && scale >= 0)) throw props.error("scale", "must be >= 0");
    props.get_bool("sample_emitters", true);          // accepted: NEE is always used
    props.get_bool("has_spectral_extinction", true);  // accepted: coefficients are RGB
    Rgb sigma_a, sigma_s;
    if (props.has("sigmaA") || props.has("sigmaS")) {
        // Mitsuba 0.6: absorption and scattering coefficients.
        sigma_a = props.get_rgb("sigmaA", Rgb(0.0f));
        sigma_s = props.get_rgb("sigmaS", Rgb(0.0f));
        if (!valid_coefficient(sigma_a)) throw props.error("sigmaA", "must be finite and >= 0");
        if (!valid_coefficient(sigma_s)) throw props.error("sigmaS", "must be finite and >= 0");
    } else {
        // Mitsuba 3: extinction and single-scattering albedo (defaults as in Mitsuba 3).
        const Rgb sigma_t = props.get_rgb("sigma_t", Rgb(1.0f));
        const Rgb albedo = props.get_rgb("albedo", Rgb(0.75f));
        if (!valid_coefficient(sigma_t)) throw props.error("sigma_t", "must be finite and >= 0");
        if (!valid_coefficient(albedo) || albedo.max() > 1.0f)
            throw props.error("albedo", "must be in [0, 1]");
        sigma_s = sigma_t * albedo;
        sigma_a = sigma_t - sigma_s;
        for (int c = 0; c < 3; ++c) sigma_a[c] = std::max(sigma_a[c], 0.0f);
    }
    const Rgb scaled_a = sigma_a * scale, scaled_s = sigma_s * scale;
    if (!(scaled_a + scaled_s).is_finite())
        throw props.error("scale", "the scaled coefficients overflow");
    // Emitted radiance L_e (source term sigma_a L_e, docs/design/media.md "Emission in media").
    const Rgb radiance = props.get_rgb("radiance", Rgb(0.0f));
    if (!valid_coefficient(radiance)) throw props.error("radiance", "must be finite and >= 0");
    return std::make_shared<HomogeneousMedium>(scaled_a, scaled_s, std::move(phase), radiance);
}

}  // namespace

std::shared_ptr<const PhaseFunction> make_phase(const Properties& props) {
    static const Plugin<std::shared_ptr<const PhaseFunction> (*)(const Properties&)> kPhases[] = {
        {"isotropic",
         [](const Properties&) -> std::shared_ptr<const PhaseFunction> {
             return std::make_shared<IsotropicPhase>();
         }},
        {"hg",
         [](const Properties& p) -> std::shared_ptr<const PhaseFunction> {
             const float g = p.get_float("g", 0.8f);  // Mitsuba 3's default
             if (!(g > -1.0f && g < 1.0f)) throw p.error("g", "must be in (-1, 1)");
             return std::make_shared<HenyeyGreenstein>(g);
         }},
    };
    return find_plugin(kPhases, props, "phase function").create(props);
}

namespace {

using Volumes = std::map<std::string, std::shared_ptr<const Volume>>;

std::shared_ptr<const Medium> make_homogeneous_plugin(const Properties& props,
                                                      std::shared_ptr<const PhaseFunction> phase,
                                                      const Volumes& volumes) {
    if (!volumes.empty())
        throw SceneError(props.where(),
                         "a homogeneous medium takes float or rgb coefficients, not volumes "
                         "(use a heterogeneous medium for volume data)");
    return make_homogeneous(props, std::move(phase));
}

std::shared_ptr<const Medium> make_heterogeneous_plugin(const Properties& props,
                                                        std::shared_ptr<const PhaseFunction> phase,
                                                        const Volumes& volumes) {
    // Each coefficient is a nested <volume name="..."> or a plain float/rgb (a constant).
    auto volume = [&](const std::string& name) -> std::shared_ptr<const Volume> {
        auto it = volumes.find(name);
        if (it != volumes.end()) {
            if (props.has(name)) throw props.error(name, "given both as a value and as a <volume>");
            return it->second;
        }
        if (!props.has(name)) return nullptr;  // the factory applies Mitsuba's default
        const Rgb value = props.get_rgb(name);
        if (name == "radiance" && !valid_coefficient(value))
            throw props.error(name, "must be finite and >= 0");
        return std::make_shared<ConstantVolume>(value);
    };
    for (const auto& [name, v] : volumes)
        if (name != "sigma_t" && name != "albedo" && name != "radiance")
            throw SceneError(props.where(), "heterogeneous medium: unknown volume \"" + name +
                                                "\" (expected sigma_t, albedo or radiance)");
    return make_heterogeneous_medium(props, volume("sigma_t"), volume("albedo"), std::move(phase),
                                     volume("radiance"));
}

const Plugin<std::shared_ptr<const Medium> (*)(
    const Properties&, std::shared_ptr<const PhaseFunction>, const Volumes&)>
    kMedia[] = {
        {"homogeneous", make_homogeneous_plugin},
        {"heterogeneous", make_heterogeneous_plugin},
};

}  // namespace

std::shared_ptr<const Medium> make_medium(
    const Properties& props, std::shared_ptr<const PhaseFunction> phase,
    const std::map<std::string, std::shared_ptr<const Volume>>& volumes) {
    const auto& plugin = find_plugin(kMedia, props, "medium");
    if (!phase) phase = std::make_shared<IsotropicPhase>();
    return plugin.create(props, std::move(phase), volumes);
}

}  // namespace render
