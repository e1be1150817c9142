#pragma once

// The algorithm table: one row per light-transport algorithm, with its name, the scene-file
// integrators it stands for, what scenes it renders correctly, the options it reads, its working
// memory, the benchmarks that run it and its factory. Every list of algorithms, every
// "supported: ..." message, the --help text, `render --describe-options` (which the scripts
// read), the memory estimate and the scene formats' integrator names are derived from it
// (docs/design/architecture.md, "Adding an algorithm").

#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/integrators/integrator.h"
#include "core/render/render_settings.h"

namespace render {

class Scene;
struct RenderOption;
struct IterationMemoryInput;
struct IterationMemoryParts;

// What a scene may contain for the algorithm to render it without bias. Every algorithm
// renders surfaces.
struct SceneSupport {
    bool homogeneous_media = false;
    bool grid_media = false;      // heterogeneous (grid) media
    bool emissive_media = false;  // media that emit (`radiance`)
    // Emitting media inside closed shapes only: they become lights (Scene::volume_lights,
    // docs/design/media.md "Emitting media as lights"); an unbounded emitting medium is refused.
    bool bounded_emissive_media = false;
};

struct Algorithm {
    std::string name;  // as in --algo, the API and EXR headers
    // Other accepted names: the Mitsuba integrator types it stands for (a scene without --algo
    // renders with the algorithm its <integrator> names), also accepted by --algo.
    std::vector<std::string> aliases;
    // The pbrt-v4 `Integrator` names it stands for (pbrt's "bdpt" is bpt).
    std::vector<std::string> pbrt_integrators;
    std::string description;  // one line for --help
    SceneSupport support;
    // Options it reads besides those every algorithm reads (RenderOption::every_algorithm).
    std::vector<std::string> options;
    // Other estimators of the same algorithm, selected by options (render option name to
    // value, e.g. bpt's importance-cached connections): each joins the furnace,
    // iteration-contract and shipped-scene tests as a case of its own.
    std::vector<std::map<std::string, std::string>> variants;
    std::unique_ptr<Integrator> (*create)(const RenderSettings&) = nullptr;
    // Converges to the image the scene describes (false for debug shading): such algorithms
    // take part in the furnace, iteration-contract and convergence tests automatically.
    bool physically_based = true;
    // Adds its working memory per iteration, besides the scene, the film and the per-thread
    // buffers, to the estimate a worker and `render --max-memory` check before rendering
    // (core/render/iteration_memory.h; no_working_memory where it keeps nothing).
    void (*iteration_memory)(const IterationMemoryInput&, IterationMemoryParts&) = nullptr;
    // The suites of scripts/bench that run it ("performance", "convergence"): they read this
    // list from `render --describe-options` instead of keeping their own.
    std::vector<std::string> benchmarks;
};

// Every algorithm, in --help order.
const std::vector<Algorithm>& algorithms();

// Adds a row after the built-in ones, for an algorithm defined elsewhere (a test's, or one
// linked in from another library). Call it before rendering starts: the table is not locked.
// Throws std::invalid_argument when the name (or an alias) is taken or a required field is
// missing (name, description, create, iteration_memory), so a row cannot silently lack one.
void register_algorithm(Algorithm row);

// The iteration_memory of an algorithm that keeps nothing per iteration beyond the per-thread
// buffers (pt, volpt, eyelight).
void no_working_memory(const IterationMemoryInput&, IterationMemoryParts&);

// The algorithm of that name or alias, or nullptr.
const Algorithm* find_algorithm(std::string_view name_or_alias);
// The same; throws std::invalid_argument "unknown algorithm "x" (supported: ...)".
const Algorithm& find_algorithm_or_throw(std::string_view name_or_alias);

// The algorithm a job renders with: `requested` (--algo, the API's settings.algorithm) when
// given, else the scene file's integrator (Mitsuba's `path` is `pt`; a pbrt scene's integrator
// is named "pbrt:NAME" by its loader, and pbrt's "bdpt" is bpt). A scene integrator
// that names no algorithm (Mitsuba's `direct`, `ptracer`, ...) throws std::invalid_argument
// asking for --algo; an unknown `requested` is left to find_algorithm_or_throw's message.
std::string job_algorithm(const std::string& requested, const std::string& scene_integrator);

// "pt, volpt, lt, ...": the names, for messages.
std::string algorithm_names();
// "  pt      path tracing\n ...": name, aliases and description per line, for --help.
std::string algorithms_help();

bool algorithm_reads(const Algorithm& algorithm, const RenderOption& option);
// "ppm, bpm, vcm": the algorithms that read the option.
std::string algorithms_reading(const RenderOption& option);

// The integrator for `settings` (settings.algorithm may be an alias).
std::unique_ptr<Integrator> make_integrator(const RenderSettings& settings);

// Throws std::invalid_argument when the algorithm would render `scene` wrongly (media it does
// not handle), naming the algorithms that can.
void check_algorithm_supports_scene(const std::string& algorithm, const Scene& scene);
// The same, and the options of `settings` that cannot render `scene` (joint connections beside
// an emitting medium, whose J1 technique toward a volume light's point is not built).
void check_algorithm_supports_scene(const RenderSettings& settings, const Scene& scene);

}  // namespace render
