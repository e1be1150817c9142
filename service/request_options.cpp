#include "service/request_options.h"

#include <stdexcept>

#include "core/util/arguments.h"

namespace render::service {

namespace {

void fold(OptionMap& options, const std::string& name, const std::string& value) {
    auto [it, inserted] = options.emplace(name, value);
    if (inserted || it->second == value) return;
    // The map may spell a number differently ("0.01" vs "1e-2"): compare canonical values.
    const RenderOption* option = find_render_option(name);
    try {
        if (option &&
            canonical_option_value(*option, it->second) == canonical_option_value(*option, value))
            return;
    } catch (const std::invalid_argument&) {
    }
    throw std::invalid_argument("settings." + name + " (" + value + ") and settings.options[\"" +
                                name + "\"] (" + it->second.substr(0, 64) + ") disagree");
}

}  // namespace

OptionMap request_options(const v1::RenderSettings& s) {
    OptionMap options(s.options().begin(), s.options().end());
    if (s.seed() != 0) fold(options, "seed", std::to_string(s.seed()));
    if (s.radius_factor() != 0) fold(options, "radius_factor", format_real(s.radius_factor()));
    if (s.alpha() != 0) fold(options, "alpha", format_real(s.alpha()));
    if (s.has_max_depth()) fold(options, "max_depth", std::to_string(s.max_depth()));
    if (s.light_path_count() != 0)
        fold(options, "light_paths", std::to_string(s.light_path_count()));
    return options;
}

std::string check_request_options(const OptionMap& options) {
    if (options.size() > 256) return "settings.options has more than 256 entries";
    for (const auto& [name, value] : options) {
        const RenderOption* option = find_render_option(name);
        if (!option)
            return "settings.options[\"" + name.substr(0, 64) + "\"] is not a render option (" +
                   render_option_names() + ")";
        try {
            canonical_option_value(*option, value);
        } catch (const std::invalid_argument& e) {
            return "settings.options[\"" + name + "\"]: " + e.what();
        }
    }
    return {};
}

void set_request_options(v1::RenderSettings& s, const OptionMap& options) {
    s.clear_options();
    for (const auto& [name, value] : options) (*s.mutable_options())[name] = value;
    s.set_radius_factor(0);
    s.set_alpha(0);
    s.set_has_max_depth(false);
    s.set_max_depth(0);
    s.set_light_path_count(0);
    auto seed = options.find("seed");
    s.set_seed(seed == options.end() ? 0 : parse_number<uint64_t>("seed", seed->second));
}

}  // namespace render::service
