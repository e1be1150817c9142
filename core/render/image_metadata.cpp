#include "core/render/image_metadata.h"

#include <algorithm>

#include "core/render/render_options.h"

namespace render {

std::map<std::string, std::string> image_metadata(const RenderSettings& settings,
                                                  const RenderedImageFacts& facts) {
    std::map<std::string, std::string> out = render_settings_metadata(settings);
    out["render:scene"] = facts.scene;
    out["render:iterations"] = std::to_string(facts.iterations);
    out["render:seconds"] = format_real(facts.seconds);
    out["render:relative_error_estimate"] = format_real(facts.relative_error);
    out["render:non_finite_samples_dropped"] = std::to_string(facts.non_finite);
    if (facts.invalid_rays > 0) out["render:invalid_rays"] = std::to_string(facts.invalid_rays);
    if (facts.target_error > 0) out["render:target_error"] = format_real(facts.target_error);
    for (const auto& [name, value] : facts.defines) out["render:define:" + name] = value;
    if (facts.vpl_candidates > 0) {
        out["render:vpl_acceptance"] =
            format_real(double(facts.vpl_accepted) / double(facts.vpl_candidates));
        out["render:vpl_candidates_per_iteration"] = format_real(
            double(facts.vpl_candidates) / double(std::max<uint64_t>(1, facts.iterations)));
    }
    return out;
}

}  // namespace render
