#include <stdexcept>

#include "core/integrators/eyelight.h"
#include "core/integrators/integrator.h"
#include "core/integrators/path_tracer.h"

namespace render {

std::unique_ptr<Integrator> make_integrator(const RenderSettings& settings) {
    const std::string& name = settings.algorithm;
    if (name == "pt" || name == "path")
        return std::make_unique<PathTracer>(settings.max_depth, settings.rr_depth);
    if (name == "eyelight") return std::make_unique<EyeLight>();
    throw std::invalid_argument("unknown algorithm \"" + name + "\" (supported: pt, eyelight)");
}

}  // namespace render
