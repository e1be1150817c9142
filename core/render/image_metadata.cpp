#include "core/render/image_metadata.h"

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
    for (const auto& [name, value] : facts.defines) out["render:define:" + name] = value;
    return out;
}

}  // namespace render
