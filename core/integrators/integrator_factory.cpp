#include <map>
#include <stdexcept>

#include "core/integrators/eyelight.h"
#include "core/integrators/integrator.h"
#include "core/integrators/path_tracer.h"
#include "core/integrators/vertex_cm.h"
#include "core/integrators/volumetric_path_tracer.h"
#include "core/media/medium.h"

namespace render {

std::unique_ptr<Integrator> make_integrator(const RenderSettings& settings) {
    const std::string& name = settings.algorithm;
    if (name == "pt" || name == "path")
        return std::make_unique<PathTracer>(settings.max_depth, settings.rr_depth);
    if (name == "eyelight") return std::make_unique<EyeLight>();
    if (name == "volpt" || name == "volpath")
        return std::make_unique<VolumetricPathTracer>(settings.max_depth, settings.rr_depth,
                                                      settings.equiangular);

    static const std::map<std::string, BidirectionalMode> bidirectional = {
        {"lt", BidirectionalMode::LightTracing}, {"bpt", BidirectionalMode::Bpt},
        {"ppm", BidirectionalMode::Ppm},         {"bpm", BidirectionalMode::Bpm},
        {"vcm", BidirectionalMode::Vcm},
    };
    auto it = bidirectional.find(name);
    if (it == bidirectional.end())
        throw std::invalid_argument("unknown algorithm \"" + name +
                                    "\" (supported: pt, volpt, lt, bpt, ppm, bpm, vcm, eyelight)");
    if (!(settings.radius_factor > 0) || !(settings.alpha > 0) || settings.alpha > 1)
        throw std::invalid_argument("radius_factor must be > 0 and alpha in (0, 1]");
    if (settings.mis_power != 1 && settings.mis_power != 2)
        throw std::invalid_argument("mis_power must be 1 (balance) or 2 (power heuristic)");
    BidirectionalConfig config;
    config.mode = it->second;
    config.max_depth = settings.max_depth;
    config.rr_depth = settings.rr_depth;
    config.radius_factor = settings.radius_factor;
    config.alpha = settings.alpha;
    config.light_path_count = settings.light_path_count;
    config.mis_power = settings.mis_power;
    return std::make_unique<VertexConnectionMerging>(config);
}

void check_algorithm_supports_scene(const std::string& algorithm, const Scene& scene) {
    if (!scene.has_media() || algorithm == "volpt" || algorithm == "volpath") return;
    const bool bidirectional = algorithm == "lt" || algorithm == "bpt" || algorithm == "ppm" ||
                               algorithm == "bpm" || algorithm == "vcm";
    if (!bidirectional)
        throw std::invalid_argument("the scene has participating media, which algorithm \"" +
                                    algorithm + "\" ignores (use volpt, or a bidirectional one)");
    // Bidirectional MIS needs exact distance-sampling densities (core/media/medium_segment.h).
    for (const auto& medium : scene.media())
        if (!medium->is_homogeneous())
            throw std::invalid_argument("algorithm \"" + algorithm +
                                        "\" handles homogeneous media only, and the scene has "
                                        "a heterogeneous medium (use volpt)");
}

}  // namespace render
