#include "core/render/algorithms.h"

#include <algorithm>
#include <stdexcept>

#include "core/base/memory_budget.h"
#include "core/integrators/bidirectional/bidirectional_integrator.h"
#include "core/integrators/eyelight.h"
#include "core/integrators/many_lights/many_light_integrator.h"
#include "core/integrators/path_tracer.h"
#include "core/integrators/volumetric_path_tracer.h"
#include "core/media/medium.h"
#include "core/render/iteration_memory.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace render {

namespace {

// The settings every algorithm of the bidirectional family reads.
BidirectionalConfig bidirectional_config(BidirectionalAlgorithm algorithm,
                                         const RenderSettings& s) {
    BidirectionalConfig config;
    config.algorithm = algorithm;
    config.subpaths = {.max_depth = s.max_depth,
                       .rr_depth = s.rr_depth,
                       .light_path_count = s.light_path_count,
                       .roulette = s.roulette};
    config.merging = {
        .radius_factor = s.radius_factor, .radius_pixels = s.radius_pixels, .alpha = s.alpha};
    config.mis_power = s.mis_power;
    return config;
}

template <BidirectionalAlgorithm algorithm>
std::unique_ptr<Integrator> make_bidirectional(const RenderSettings& s) {
    return std::make_unique<BidirectionalIntegrator>(bidirectional_config(algorithm, s));
}

// vpl and ic: the VPLs (light paths per iteration) and their clamp; each adds its own options.
ManyLightConfig many_light_config(ManyLightEstimator estimator, const RenderSettings& s) {
    ManyLightConfig config;
    config.estimator = estimator;
    config.subpaths = {
        .max_depth = s.max_depth, .rr_depth = s.rr_depth, .light_path_count = s.vpl_paths};
    config.clamp = {
        .factor = s.vpl_clamp,
        .schedule = s.vpl_clamp_shrinking ? VplClampSchedule::Shrinking : VplClampSchedule::Fixed};
    return config;
}

// The options of the bidirectional family; merging ones only where merging happens.
const std::vector<std::string> kConnecting = {"max_depth",
                                              "rr_depth",
                                              "roulette",
                                              "light_paths",
                                              "mis",
                                              "adaptive",
                                              "adaptive_min_iterations",
                                              "adaptive_round"};
const std::vector<std::string> kMerging = {
    "max_depth",     "rr_depth",      "roulette", "light_paths", "mis",
    "radius_factor", "radius_pixels", "alpha",    "adaptive",    "adaptive_min_iterations",
    "adaptive_round"};

// The working memory of the bidirectional family's rows: its stored light paths.
template <bool merges, bool volume_estimators = false>
void light_path_memory(const IterationMemoryInput& in, IterationMemoryParts& parts) {
    add_light_path_memory(in, {.merges = merges, .volume_estimators = volume_estimators}, parts);
}

const std::vector<std::string> kAllBenchmarks = {"performance", "convergence"};

// Throws std::invalid_argument naming the required fields a row lacks: the built-in rows and
// registered ones are held to the same list.
void check_required_fields(const Algorithm& row) {
    std::string missing;
    if (row.name.empty()) missing += " name";
    if (row.description.empty()) missing += " description";
    if (!row.create) missing += " create";
    if (!row.iteration_memory) missing += " iteration_memory";
    if (!missing.empty())
        throw std::invalid_argument("algorithm row \"" + row.name + "\" lacks:" + missing);
}

// Rows name only the fields they set; the others keep their member defaults (GCC's
// -Wextra would warn about every omitted field of a designated initializer).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
std::vector<Algorithm>& table() {
    // One row per algorithm. A new algorithm: its integrator's own file(s) and a row here.
    static std::vector<Algorithm> rows = {
        {.name = "pt",
         .aliases = {"path"},
         .pbrt_integrators = {"path"},
         .description = "path tracing with next-event estimation (surfaces only)",
         .options = {"max_depth", "rr_depth", "roulette", "adaptive", "adaptive_min_iterations",
                     "adaptive_round"},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             return std::make_unique<PathTracer>(s.max_depth, s.rr_depth, s.roulette);
         },
         .iteration_memory = no_working_memory,
         .benchmarks = kAllBenchmarks},
        {.name = "volpt",
         .aliases = {"volpath"},
         .pbrt_integrators = {"volpath"},
         .description =
             "volumetric path tracing: delta/ratio tracking, equi-angular and joint sampling (any "
             "media)",
         .support = {.homogeneous_media = true, .grid_media = true, .emissive_media = true},
         .options = {"max_depth", "rr_depth", "equiangular", "jis", "volpt_technique", "adaptive",
                     "adaptive_min_iterations", "adaptive_round"},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             return std::make_unique<VolumetricPathTracer>(s.max_depth, s.rr_depth, s.equiangular,
                                                           s.jis, s.volpt_technique);
         },
         .iteration_memory = no_working_memory,
         .benchmarks = kAllBenchmarks},
        {.name = "lt",
         .pbrt_integrators = {"lightpath"},
         .description =
             "light tracing (homogeneous and grid media, emitting media in closed shapes)",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = kConnecting,
         .create = make_bidirectional<BidirectionalAlgorithm::LightTracing>,
         // Its light vertices are connected to the camera as they are traced, never stored.
         .iteration_memory = no_working_memory,
         .benchmarks = kAllBenchmarks},
        {.name = "bpt",
         .pbrt_integrators = {"bdpt"},
         .description =
             "bidirectional path tracing (homogeneous and grid media, emitting media in closed "
             "shapes); --connections ic: importance-cached connections",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = {"max_depth", "rr_depth", "roulette", "light_paths", "mis", "connections",
                     "joint_connections", "ic_light_paths", "connection_samples",
                     "ic_record_density", "ic_heuristic", "adaptive", "adaptive_min_iterations",
                     "adaptive_round"},
         .variants = {{{"connections", "ic"}},
                      {{"joint_connections", "on"}},
                      {{"joint_connections", "all"}}},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             BidirectionalConfig config = bidirectional_config(BidirectionalAlgorithm::Bpt, s);
             config.joint = {.j1 = s.joint_connections, .j2 = s.joint2_connections};
             config.ic_connections = {.enabled = s.ic_connections, .light_paths = s.ic_light_paths};
             config.cache = {.record_density = s.ic_record_density,
                             .samples = s.connection_samples,
                             .heuristic = s.ic_heuristic};
             return std::make_unique<BidirectionalIntegrator>(config);
         },
         .iteration_memory =
             [](const IterationMemoryInput& in, IterationMemoryParts& parts) {
                 add_light_path_memory(in, {.joint2_possible = true}, parts);
                 if (in.settings.ic_connections)
                     add_importance_cache_memory(
                         in,
                         saturating_product(in.settings.ic_light_paths, in.light_vertices_per_path),
                         parts);
             },
         .benchmarks = kAllBenchmarks},
        {.name = "ppm",
         .pbrt_integrators = {"sppm"},
         .description = "progressive photon mapping (homogeneous and grid media: photon points; "
                        "emitting media in closed shapes)",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = kMerging,
         .create = make_bidirectional<BidirectionalAlgorithm::Ppm>,
         .iteration_memory = light_path_memory<true>,
         .benchmarks = kAllBenchmarks},
        {.name = "bpm",
         .description =
             "bidirectional photon mapping (homogeneous and grid media, emitting media in closed "
             "shapes)",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = kMerging,
         .create = make_bidirectional<BidirectionalAlgorithm::Bpm>,
         .iteration_memory = light_path_memory<true>,
         .benchmarks = kAllBenchmarks},
        {.name = "vcm",
         .description = "vertex connection and merging (homogeneous and grid media, emitting "
                        "media in closed shapes)",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = {"max_depth", "rr_depth", "roulette", "light_paths", "mis", "radius_factor",
                     "radius_pixels", "alpha", "joint_connections", "adaptive",
                     "adaptive_min_iterations", "adaptive_round"},
         .variants = {{{"joint_connections", "on"}}},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             // J2's factors in the merge weights are not derived (docs/design/media.md).
             if (s.joint2_connections)
                 throw std::invalid_argument(
                     "--joint-connections all (J2 connections) is bpt only: vcm's merge weights "
                     "have no J2 factors; use --joint-connections on (J1) with vcm");
             BidirectionalConfig config = bidirectional_config(BidirectionalAlgorithm::Vcm, s);
             config.joint.j1 = s.joint_connections;
             return std::make_unique<BidirectionalIntegrator>(config);
         },
         .iteration_memory = light_path_memory<true>,
         .benchmarks = kAllBenchmarks},
        {.name = "upbp",
         .description =
             "unified points, beams and paths (homogeneous and grid media, emitting media in "
             "closed shapes): vcm's connections and merges with query beams (photon points "
             "gathered along whole camera segments in media) and photon beams (light-path "
             "segments in media gathered by camera segments)",
         .support = {.homogeneous_media = true, .grid_media = true, .bounded_emissive_media = true},
         .options = {"max_depth",
                     "rr_depth",
                     "roulette",
                     "light_paths",
                     "mis",
                     "radius_factor",
                     "radius_pixels",
                     "alpha",
                     "vertex_connections",
                     "surface_merging",
                     "photon_points",
                     "query_beams",
                     "photon_beams",
                     "photon_beam_length",
                     "photon_beam_eta",
                     "photon_beam_paths",
                     "query_beam_paths",
                     "volume_radius_factor",
                     "volume_alpha",
                     "adaptive",
                     "adaptive_min_iterations",
                     "adaptive_round"},
         // Query and photon beams beside connections only; query beams, then photon beams (long,
         // with the other eta_1), as the only estimator in media.
         .variants = {{{"surface_merging", "off"}, {"photon_points", "off"}},
                      {{"vertex_connections", "off"},
                       {"photon_points", "off"},
                       {"photon_beams", "off"}},
                      {{"vertex_connections", "off"},
                       {"photon_points", "off"},
                       {"query_beams", "off"},
                       {"photon_beam_length", "long"},
                       {"photon_beam_eta", "2r"}}},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             BidirectionalConfig config = bidirectional_config(BidirectionalAlgorithm::Upbp, s);
             config.upbp = {.vertex_connections = s.vertex_connections,
                            .surface_merging = s.surface_merging,
                            .photon_points = s.photon_points,
                            .query_beams = s.query_beams,
                            .photon_beams = s.photon_beams,
                            .short_photon_beams = s.short_photon_beams,
                            .photon_beam_eta = s.photon_beam_eta,
                            .photon_beam_paths = s.photon_beam_paths,
                            .query_beam_paths = s.query_beam_paths,
                            .volume_radius_factor = s.volume_radius_factor,
                            .volume_alpha = s.volume_alpha};
             return std::make_unique<BidirectionalIntegrator>(config);
         },
         // Any stored vertex may lie in a medium: a photon beam and a ball of the query beams'
         // BVH each.
         .iteration_memory = light_path_memory<true, true>},
        {.name = "vpl",
         .aliases = {"instant_radiosity"},
         .description = "many-light rendering: virtual point lights from light paths (surfaces "
                        "only; no caustics through delta vertices)",
         .options = {"max_depth", "rr_depth", "vpl_paths", "vpl_clamp", "vpl_clamp_schedule",
                     "vpl_distribution", "importance_records", "vpl_min_probability", "adaptive",
                     "adaptive_min_iterations", "adaptive_round"},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             ManyLightConfig config = many_light_config(ManyLightEstimator::Vpl, s);
             config.importance = {.enabled = s.vpl_importance,
                                  .records = s.importance_records,
                                  .min_probability = s.vpl_min_probability};
             return std::make_unique<ManyLightIntegrator>(config);
         },
         .iteration_memory =
             [](const IterationMemoryInput& in, IterationMemoryParts& parts) {
                 add_vpl_memory(in, in.settings.vpl_importance, parts);
             },
         .benchmarks = {"convergence"}},
        {.name = "ic",
         .aliases = {"importance_caching"},
         .description = "many-light rendering with importance caching: each shading point draws "
                        "a few VPLs from the distributions of nearby camera records (surfaces "
                        "only; no caustics through delta vertices)",
         .options = {"max_depth", "rr_depth", "vpl_paths", "vpl_clamp", "vpl_clamp_schedule",
                     "ic_record_density", "ic_samples", "ic_heuristic", "ic_optimise",
                     "ic_distributions", "adaptive", "adaptive_min_iterations", "adaptive_round"},
         .create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
             ManyLightConfig config = many_light_config(ManyLightEstimator::Ic, s);
             config.cache = {.record_density = s.ic_record_density,
                             .samples = s.ic_samples,
                             .heuristic = s.ic_heuristic,
                             .power_only = s.ic_power_only,
                             .optimise = s.ic_optimise};
             return std::make_unique<ManyLightIntegrator>(config);
         },
         .iteration_memory =
             [](const IterationMemoryInput& in, IterationMemoryParts& parts) {
                 add_vpl_memory(in, false, parts);
                 add_importance_cache_memory(
                     in, saturating_product(in.settings.vpl_paths, in.light_vertices_per_path),
                     parts);
             },
         .benchmarks = {"convergence"}},
        {.name = "eyelight",
         .description = "debug shading: |cos| at the first hit (surfaces only)",
         .create = [](const RenderSettings&) -> std::unique_ptr<Integrator> {
             return std::make_unique<EyeLight>();
         },
         .physically_based = false,
         .iteration_memory = no_working_memory},
    };
    // A built-in row that lacks a required field fails at its first use, as a registered one.
    [[maybe_unused]] static const bool checked = [] {
        for (const Algorithm& row : rows) check_required_fields(row);
        return true;
    }();
    return rows;
}
#pragma GCC diagnostic pop

}  // namespace

const std::vector<Algorithm>& algorithms() {
    return table();
}

void no_working_memory(const IterationMemoryInput&, IterationMemoryParts&) {}

void register_algorithm(Algorithm row) {
    check_required_fields(row);
    std::vector<std::string> names = row.aliases;
    names.push_back(row.name);
    for (const std::string& n : names)
        if (find_algorithm(n)) throw std::invalid_argument("algorithm name \"" + n + "\" is taken");
    table().push_back(std::move(row));
}

const Algorithm* find_algorithm(std::string_view name) {
    // A pbrt scene's integrator, as its loader names it.
    constexpr std::string_view kPbrt = "pbrt:";
    if (name.starts_with(kPbrt)) {
        const std::string_view pbrt = name.substr(kPbrt.size());
        for (const Algorithm& a : table())
            for (const std::string& n : a.pbrt_integrators)
                if (n == pbrt) return &a;
        return nullptr;
    }
    for (const Algorithm& a : table()) {
        if (a.name == name) return &a;
        for (const std::string& alias : a.aliases)
            if (alias == name) return &a;
    }
    return nullptr;
}

const Algorithm& find_algorithm_or_throw(std::string_view name) {
    if (const Algorithm* a = find_algorithm(name)) return *a;
    throw std::invalid_argument("unknown algorithm \"" + std::string(name.substr(0, 64)) +
                                "\" (supported: " + algorithm_names() + ")");
}

std::string job_algorithm(const std::string& requested, const std::string& scene_integrator) {
    if (!requested.empty() || find_algorithm(scene_integrator))
        return requested.empty() ? scene_integrator : requested;
    throw std::invalid_argument(
        "the scene's integrator \"" + scene_integrator.substr(0, 64) +
        "\" is not an algorithm of this renderer: choose one with --algo (" + algorithm_names() +
        ")");
}

std::string algorithm_names() {
    std::string out;
    for (const Algorithm& a : table()) out += (out.empty() ? "" : ", ") + a.name;
    return out;
}

std::string algorithms_help() {
    std::string out;
    for (const Algorithm& a : table()) {
        std::string head = "  " + a.name;
        for (const std::string& alias : a.aliases) head += ", " + alias;
        head.resize(std::max<size_t>(head.size() + 2, 24), ' ');
        out += head + a.description + "\n";
    }
    return out;
}

bool algorithm_reads(const Algorithm& algorithm, const RenderOption& option) {
    if (option.every_algorithm) return true;
    for (const std::string& name : algorithm.options)
        if (name == option.name) return true;
    return false;
}

std::string algorithms_reading(const RenderOption& option) {
    std::string out;
    for (const Algorithm& a : table())
        if (algorithm_reads(a, option)) out += (out.empty() ? "" : ", ") + a.name;
    return out.empty() ? "none" : out;
}

std::unique_ptr<Integrator> make_integrator(const RenderSettings& settings) {
    return find_algorithm_or_throw(settings.algorithm).create(settings);
}

void check_algorithm_supports_scene(const std::string& name, const Scene& scene) {
    const Algorithm& algorithm = find_algorithm_or_throw(name);
    bool homogeneous = false, grid = false;
    std::string emissive;  // the first emitting medium's name
    for (size_t i = 0; i < scene.media().size(); ++i) {
        const Medium& medium = *scene.media()[i];
        (medium.is_homogeneous() ? homogeneous : grid) = true;
        if (medium.is_emissive() && emissive.empty()) {
            emissive = scene.medium_name(i);
            if (emissive.empty()) emissive = "a medium";
        }
    }
    const bool unbounded = !scene.unbounded_emitting_media().empty();
    const auto supported = [&](const Algorithm& a) {
        return (!homogeneous || a.support.homogeneous_media) && (!grid || a.support.grid_media) &&
               (emissive.empty() || a.support.emissive_media ||
                (a.support.bounded_emissive_media && !unbounded));
    };
    if (supported(algorithm)) return;
    if (unbounded && algorithm.support.bounded_emissive_media) {
        std::string can;
        for (const Algorithm& a : table())
            if (a.support.emissive_media) can += (can.empty() ? "" : ", ") + a.name;
        throw std::invalid_argument(
            "the scene's " + scene.unbounded_emitting_media().front() + "; algorithm \"" +
            algorithm.name +
            "\" renders emitting media only inside closed shapes (as lights), use " + can);
    }
    std::string can;
    for (const Algorithm& a : table())
        if (supported(a)) can += (can.empty() ? "" : ", ") + a.name;
    if (!emissive.empty() && !algorithm.support.emissive_media)
        throw std::invalid_argument("the scene's " + emissive +
                                    " emits light (radiance), which algorithm \"" + algorithm.name +
                                    "\" does not render (use " + can + ")");
    throw std::invalid_argument(
        "the scene has " +
        std::string(grid ? "a heterogeneous (grid) medium" : "participating media") +
        ", which algorithm \"" + algorithm.name + "\" does not render correctly (use " + can + ")");
}

void check_algorithm_supports_scene(const RenderSettings& settings, const Scene& scene) {
    check_algorithm_supports_scene(settings.algorithm, scene);
    const Algorithm& algorithm = find_algorithm_or_throw(settings.algorithm);
    // Only the algorithms that read the option: the others ignore it. The weights count a J1
    // technique at s = 1 toward every light, and toward a volume light's point none samples.
    const bool reads_joint = std::find(algorithm.options.begin(), algorithm.options.end(),
                                       std::string("joint_connections")) != algorithm.options.end();
    if (reads_joint && settings.joint_connections && !scene.volume_lights().empty())
        throw std::invalid_argument(
            "--joint-connections " + std::string(settings.joint2_connections ? "all" : "on") +
            " does not render emitting media yet (the scene's emitting media are lights, and no "
            "joint connection samples a point of them); use --joint-connections off with \"" +
            algorithm.name + "\", or volpt");
}

}  // namespace render
