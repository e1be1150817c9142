#pragma once

// The EXR header of a rendered image, the same for `render` and the server: render:algorithm
// and one render:NAME per option the algorithm reads (render_options.h), and these facts.

#include <cstdint>
#include <map>
#include <string>

#include "core/render/render_settings.h"

namespace render {

struct RenderedImageFacts {
    std::string scene;  // the scene file as the user named it
    uint64_t iterations = 0;
    double seconds = 0;
    double relative_error = 0;                   // estimate_relative_error()
    uint64_t non_finite = 0;                     // non-finite samples dropped
    std::map<std::string, std::string> defines;  // -D overrides, as render:define:NAME
    // vpl with the importance-driven distribution: VPL candidates and accepted ones over all
    // iterations (render:vpl_acceptance, render:vpl_candidates_per_iteration when non-zero).
    uint64_t vpl_candidates = 0, vpl_accepted = 0;
    double target_error = 0;    // the job's target (render:target_error when > 0)
    uint64_t invalid_rays = 0;  // rays not traced (render:invalid_rays when non-zero)
};

std::map<std::string, std::string> image_metadata(const RenderSettings& settings,
                                                  const RenderedImageFacts& facts);

}  // namespace render
