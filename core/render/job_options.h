#pragma once

// What a render job asks for on a command line besides its output: the algorithm, when to stop,
// the film, the scene's defines and the render options. `render` and `client submit` declare
// exactly these flags through add_job_options, with the same checks and limits.

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "core/render/render_options.h"

namespace render {

class ArgumentParser;

struct JobOptions {
    std::string algorithm;                       // "" = the scene's integrator
    std::optional<uint64_t> iterations;          // per frame
    std::optional<double> seconds;               // time budget per frame
    std::optional<double> target_error;          // stop a frame at this estimated error
    int width = 0, height = 0;                   // 0 = the scene's film
    std::map<std::string, std::string> defines;  // -D overrides of the scene's <default>s
    OptionMap options;                           // the render options table's
};

// Declares --algo, --iterations (--spp), --time, --target-error, --resolution, -D and every
// render option.
void add_job_options(ArgumentParser& parser, JobOptions& job);

}  // namespace render
