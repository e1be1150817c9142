#include "core/render/render_options.h"

#include <charconv>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "core/render/algorithms.h"
#include "core/scene/scene.h"
#include "core/util/arguments.h"

#include <nlohmann/json.hpp>

namespace render {

namespace {

int to_int(const std::string& text) {
    return parse_number<int>("", text);
}
double to_real(const std::string& text) {
    return parse_number<double>("", text);
}

// Rows name only the fields they set; the others keep their member defaults (GCC's
// -Wextra would warn about every omitted field of a designated initializer).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
const std::vector<RenderOption>& table() {
    // One row per option. A new option: a row here, the field in RenderSettings, and its name
    // in the rows of the algorithms that read it (algorithms.cpp).
    static const std::vector<RenderOption> rows = {
        {.name = "seed",
         .flag = "--seed",
         .metavar = "S",
         .type = OptionType::Unsigned,
         .help = "random seed: part of every random stream's key",
         .default_text = "0",
         .every_algorithm = true,
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.seed = parse_number<uint64_t>("", v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.seed); }},
        {.name = "max_depth",
         .flag = "--max-depth",
         .metavar = "D",
         .type = OptionType::Integer,
         .help = "longest path in segments (Mitsuba's meaning; -1 = unbounded, 1 = emitters "
                 "seen directly)",
         .min = -1,
         .max = 2147483647,
         .default_text = "the scene's max_depth",
         .apply = [](RenderSettings& s, const std::string& v) { s.max_depth = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.max_depth); }},
        {.name = "rr_depth",
         .flag = "--rr-depth",
         .metavar = "D",
         .type = OptionType::Integer,
         .help = "path depth from which Russian roulette may end paths",
         .min = 0,
         .max = 2147483647,
         .default_text = "the scene's rr_depth, else 5",
         .apply = [](RenderSettings& s, const std::string& v) { s.rr_depth = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.rr_depth); }},
        {.name = "roulette",
         .flag = "--roulette",
         .metavar = "throughput|albedo",
         .type = OptionType::Choice,
         .help = "how Russian roulette ends paths. throughput: from --rr-depth on, survive with "
                 "min(0.95, throughput); albedo: at every scattering, survive with min(1, the "
                 "sampled direction's weight f cos / pdf), as SmallVCM plays it "
                 "(core/integrators/roulette.h)",
         .choices = {"throughput", "albedo"},
         .default_text = "throughput",
         .apply =
             [](RenderSettings& s, const std::string& v) {
                 s.roulette = v == "albedo" ? RoulettePolicy::Albedo : RoulettePolicy::Throughput;
             },
         .format = [](const RenderSettings& s) -> std::string {
             return s.roulette == RoulettePolicy::Albedo ? "albedo" : "throughput";
         }},
        {.name = "radius_factor",
         .flag = "--radius-factor",
         .metavar = "F",
         .type = OptionType::Real,
         .help = "initial merging radius as a fraction of the scene's bounding-sphere radius (0 = "
                 "from --radius-pixels)",
         .min = 0,
         .max = 1000,
         .default_text = format_real(RenderSettings().radius_factor),
         .apply = [](RenderSettings& s, const std::string& v) { s.radius_factor = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.radius_factor); }},
        {.name = "radius_pixels",
         .flag = "--radius-pixels",
         .metavar = "K",
         .type = OptionType::Real,
         .help = "initial merging radius in pixel footprints at the scene (the pixel's side at "
                 "the camera's distance to the scene's bounding-sphere centre); used when "
                 "--radius-factor is 0",
         .min = 0,
         .max = 1e6,
         .min_exclusive = true,
         .default_text = format_real(RenderSettings().radius_pixels),
         .apply = [](RenderSettings& s, const std::string& v) { s.radius_pixels = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.radius_pixels); }},
        {.name = "alpha",
         .flag = "--alpha",
         .metavar = "A",
         .type = OptionType::Real,
         .help = "merging radius reduction: r_i = r_1 i^((A-1)/2)",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = format_real(RenderSettings().alpha),
         .apply = [](RenderSettings& s, const std::string& v) { s.alpha = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.alpha); }},
        {.name = "vertex_connections",
         .flag = "--vertex-connections",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "upbp: the connection techniques of bidirectional path tracing (off: merges only, "
                 "as bpm with the other estimators)",
         .choices = {"on", "off"},
         .default_text = "on",
         .apply = [](RenderSettings& s, const std::string& v) { s.vertex_connections = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.vertex_connections ? "on" : "off";
         }},
        {.name = "surface_merging",
         .flag = "--surface-merging",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "upbp: merging at surfaces (photon mapping's estimator)",
         .choices = {"on", "off"},
         .default_text = "on",
         .apply = [](RenderSettings& s, const std::string& v) { s.surface_merging = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.surface_merging ? "on" : "off";
         }},
        {.name = "photon_points",
         .flag = "--photon-points",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "upbp: photon points merged with distance-sampled eye vertices in media (P-P3D)",
         .choices = {"on", "off"},
         .default_text = "on",
         .effective_with = {{"volume_radius_factor", "0.02"}},
         .apply = [](RenderSettings& s, const std::string& v) { s.photon_points = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.photon_points ? "on" : "off";
         }},
        {.name = "query_beams",
         .flag = "--query-beams",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "upbp: photon points gathered along whole camera segments in media, the beam "
                 "radiance estimate (P-B2D)",
         .choices = {"on", "off"},
         .default_text = "on",
         .apply = [](RenderSettings& s, const std::string& v) { s.query_beams = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.query_beams ? "on" : "off";
         }},
        {.name = "photon_beams",
         .flag = "--photon-beams",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "upbp: light-path segments in media stored as photon beams and gathered by "
                 "camera segments with a 1-D kernel (B-B1D; short beams in chromatic grids on "
                 "one-piece segments only)",
         .choices = {"on", "off"},
         .default_text = "on",
         .apply = [](RenderSettings& s, const std::string& v) { s.photon_beams = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.photon_beams ? "on" : "off";
         }},
        {.name = "photon_beam_length",
         .flag = "--photon-beam-length",
         .metavar = "short|long",
         .type = OptionType::Choice,
         .help = "upbp: photon beams end at the light path's sampled distance (short) or at the "
                 "next surface (long)",
         .choices = {"short", "long"},
         .default_text = "short",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.short_photon_beams = v == "short"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.short_photon_beams ? "short" : "long";
         }},
        {.name = "photon_beam_eta",
         .flag = "--photon-beam-eta",
         .metavar = "r/2|2r",
         .type = OptionType::Choice,
         .help = "upbp: the photon beams' MIS constant eta_1: SmallUPBP's r/2 or the 1-D "
                 "kernel's support 2r",
         .choices = {"r/2", "2r"},
         .default_text = "r/2",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.photon_beam_eta = v == "2r" ? 2.0 : 0.5; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.photon_beam_eta == 2.0 ? "2r" : "r/2";
         }},
        {.name = "photon_beam_paths",
         .flag = "--photon-beam-paths",
         .metavar = "F",
         .type = OptionType::Real,
         .help = "upbp: fraction of each iteration's light paths (the first ones, at least one) "
                 "whose segments in media become photon beams; the beams' normalisation and MIS "
                 "weights count those paths",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = format_real(RenderSettings().photon_beam_paths),
         .apply = [](RenderSettings& s, const std::string& v) { s.photon_beam_paths = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.photon_beam_paths); }},
        {.name = "query_beam_paths",
         .flag = "--query-beam-paths",
         .metavar = "F",
         .type = OptionType::Real,
         .help = "upbp: fraction of each iteration's light paths (the first ones, at least one) "
                 "whose photon points query beams gather; the query beams' normalisation and MIS "
                 "weights count those paths",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = format_real(RenderSettings().query_beam_paths),
         .apply = [](RenderSettings& s, const std::string& v) { s.query_beam_paths = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.query_beam_paths); }},
        {.name = "volume_radius_factor",
         .flag = "--volume-radius-factor",
         .metavar = "F",
         .type = OptionType::Real,
         .help =
             "upbp: initial radius of photon points, query beams and photon beams as a fraction "
             "of the scene's bounding-sphere radius (0 = as --radius-factor, reduced with --alpha)",
         .min = 0,
         .max = 1000,
         .default_text = "0",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.volume_radius_factor = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.volume_radius_factor); }},
        {.name = "volume_alpha",
         .flag = "--volume-alpha",
         .metavar = "A",
         .type = OptionType::Real,
         .help = "upbp, with --volume-radius-factor: radius reduction of the volume estimators, "
                 "r_i = r_1 i^((A-1)/d) for a kernel of dimension d (3: points, 2: query beams, 1: "
                 "photon beams)",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = format_real(RenderSettings().volume_alpha),
         .effective_with = {{"volume_radius_factor", "0.02"}},
         .apply = [](RenderSettings& s, const std::string& v) { s.volume_alpha = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.volume_alpha); }},
        {.name = "light_paths",
         .flag = "--light-paths",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "light paths per iteration (0 = one per pixel)",
         .min = 0,
         .max = 100000000,
         .default_text = "0",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.light_path_count = parse_number<uint64_t>("", v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.light_path_count); }},
        {.name = "mis",
         .flag = "--mis",
         .metavar = "power|balance",
         .type = OptionType::Choice,
         .help = "multiple importance sampling heuristic of the bidirectional family",
         .choices = {"power", "balance"},
         .default_text = "power",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.mis_power = v == "balance" ? 1 : 2; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.mis_power == 1 ? "balance" : "power";
         }},
        {.name = "equiangular",
         .flag = "--equiangular",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "equi-angular sampling of scattering toward finite lights, combined by MIS "
                 "with distance sampling (off: distance sampling only)",
         .choices = {"on", "off"},
         .default_text = "on",
         .negated_flag = "--no-equiangular",
         .negated_value = "off",
         .apply = [](RenderSettings& s, const std::string& v) { s.equiangular = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.equiangular ? "on" : "off";
         }},
        {.name = "jis",
         .flag = "--jis",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "joint path sampling of double scattering on the camera ray in homogeneous "
                 "media, combined by MIS with the other techniques (volpt)",
         .choices = {"on", "off"},
         .default_text = "on",
         .apply = [](RenderSettings& s, const std::string& v) { s.jis = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string { return s.jis ? "on" : "off"; }},
        {.name = "volpt_technique",
         .flag = "--volpt-technique",
         .metavar = "all|dl|j3",
         .type = OptionType::Choice,
         .help = "diagnostic: the techniques that sample double scattering (volpt). all: the "
                 "MIS of every technique; dl: distance and light sampling only, unweighted (no "
                 "equi-angular or joint sampling); j3: joint sampling alone, unweighted, for the "
                 "paths it can produce. Each is unbiased; dl and j3 are for measuring "
                 "convergence rates (docs/design/media.md, \"Joint path sampling\")",
         .choices = {"all", "dl", "j3"},
         .default_text = "all",
         .apply =
             [](RenderSettings& s, const std::string& v) {
                 s.volpt_technique = v == "dl"   ? VolptTechnique::DistanceLight
                                     : v == "j3" ? VolptTechnique::Joint
                                                 : VolptTechnique::All;
             },
         .format = [](const RenderSettings& s) -> std::string {
             switch (s.volpt_technique) {
                 case VolptTechnique::DistanceLight:
                     return "dl";
                 case VolptTechnique::Joint:
                     return "j3";
                 case VolptTechnique::All:
                     break;
             }
             return "all";
         }},
        {.name = "joint_connections",
         .flag = "--joint-connections",
         .metavar = "off|on|all",
         .type = OptionType::Choice,
         .help = "joint connections in homogeneous media: on: each eye segment in a "
                 "medium also joins the vertices of the pixel's light path through a medium "
                 "vertex sampled toward each (J1, vertex-segment), and to a light point "
                 "(equi-angular next-event estimation); all: J1 and J2 (segment-segment: the "
                 "light path's vertices resampled on their light rays in homogeneous media, bpt "
                 "only); combined "
                 "by MIS (bpt, vcm; off by default: on the fog box J1 halves the variance but "
                 "doubles the time per iteration, equal-time error 0.96-1.05x; "
                 "docs/results/joint-sampling.md)",
         .choices = {"off", "on", "all"},
         .default_text = "off",
         .apply =
             [](RenderSettings& s, const std::string& v) {
                 s.joint_connections = v != "off";
                 s.joint2_connections = v == "all";
             },
         .format = [](const RenderSettings& s) -> std::string {
             return s.joint2_connections ? "all" : s.joint_connections ? "on" : "off";
         }},
        {.name = "vpl_paths",
         .flag = "--vpl-paths",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "light paths per iteration whose non-delta vertices become virtual point "
                 "lights (each pixel connects to all of them)",
         .min = 1,
         .max = 1000000,
         .default_text = std::to_string(RenderSettings().vpl_paths),
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.vpl_paths = parse_number<uint64_t>("", v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.vpl_paths); }},
        {.name = "vpl_clamp",
         .flag = "--vpl-clamp",
         .metavar = "C",
         .type = OptionType::Real,
         .help = "clamp the VPL geometry term at distance C x the scene's bounding-sphere "
                 "radius (biased; 0 = off)",
         .min = 0,
         .max = 1,
         .default_text = "0",
         .apply = [](RenderSettings& s, const std::string& v) { s.vpl_clamp = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.vpl_clamp); }},
        {.name = "vpl_clamp_schedule",
         .flag = "--vpl-clamp-schedule",
         .metavar = "shrinking|fixed",
         .type = OptionType::Choice,
         .help = "shrinking: the clamp distance falls as i^(-1/4) with the iteration index, so "
                 "the image converges to the unclamped one; fixed: the same clamp every "
                 "iteration",
         .choices = {"shrinking", "fixed"},
         .default_text = "shrinking",
         .effective_with = {{"vpl_clamp", "0.05"}},
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.vpl_clamp_shrinking = v == "shrinking"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.vpl_clamp_shrinking ? "shrinking" : "fixed";
         }},
        {.name = "vpl_distribution",
         .flag = "--vpl-distribution",
         .metavar = "uniform|importance",
         .type = OptionType::Choice,
         .help = "importance: keep each VPL with a probability from its estimated contribution "
                 "to the image (camera points of the same iteration), dividing its power by it "
                 "(unbiased); uniform: keep every VPL",
         .choices = {"uniform", "importance"},
         .default_text = "uniform",
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.vpl_importance = v == "importance"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.vpl_importance ? "importance" : "uniform";
         }},
        {.name = "importance_records",
         .flag = "--importance-records",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "camera points per iteration that estimate each VPL's contribution (one shadow "
                 "ray per point and VPL)",
         .min = 1,
         .max = 100000,
         .default_text = "100",
         .effective_with = {{"vpl_distribution", "importance"}},
         .apply = [](RenderSettings& s, const std::string& v) { s.importance_records = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.importance_records); }},
        {.name = "vpl_min_probability",
         .flag = "--vpl-min-probability",
         .metavar = "P",
         .type = OptionType::Real,
         .help = "lowest probability of keeping a VPL (> 0: a VPL no camera point sees is still "
                 "kept sometimes, which keeps the estimator unbiased)",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = "0.05",
         .effective_with = {{"vpl_distribution", "importance"}},
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.vpl_min_probability = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.vpl_min_probability); }},
        {.name = "ic_record_density",
         .flag = "--ic-record-density",
         .metavar = "D",
         .type = OptionType::Real,
         .help = "importance records per pixel, on a jittered screen grid (each holds four "
                 "distributions over the iteration's VPLs: one shadow ray per record and VPL)",
         .min = 0,
         .max = 1,
         .min_exclusive = true,
         .default_text = "0.0625",
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_record_density = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.ic_record_density); }},
        {.name = "ic_samples",
         .flag = "--ic-samples",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "VPLs drawn per technique (full, unoccluded, bounded, conservative) at each "
                 "shading point: 4 N shadow rays",
         .min = 1,
         .max = 4096,
         .default_text = "4",
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_samples = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.ic_samples); }},
        {.name = "ic_heuristic",
         .flag = "--ic-heuristic",
         .metavar = "alpha-max|balance|power",
         .type = OptionType::Choice,
         .help = "how the four techniques' samples are weighted: the paper's alpha-max "
                 "heuristic, or the balance or power heuristic",
         .choices = {"alpha-max", "balance", "power"},
         .default_text = "alpha-max",
         .apply =
             [](RenderSettings& s, const std::string& v) {
                 s.ic_heuristic = v == "balance" ? IcHeuristic::Balance
                                  : v == "power" ? IcHeuristic::Power
                                                 : IcHeuristic::AlphaMax;
             },
         .format = [](const RenderSettings& s) -> std::string {
             return s.ic_heuristic == IcHeuristic::Balance ? "balance"
                    : s.ic_heuristic == IcHeuristic::Power ? "power"
                                                           : "alpha-max";
         }},
        {.name = "ic_optimise",
         .flag = "--ic-optimise",
         .metavar = "on|off",
         .type = OptionType::Choice,
         .help = "with alpha-max: at each record keep every VPL only in the table of the "
                 "technique alpha-max credits it to there, and renormalise (the thesis's "
                 "distribution optimisation)",
         .choices = {"off", "on"},
         .default_text = "off",
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_optimise = v == "on"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.ic_optimise ? "on" : "off";
         }},
        {.name = "ic_distributions",
         .flag = "--ic-distributions",
         .metavar = "records|power",
         .type = OptionType::Choice,
         .help = "records: draw VPLs from the importance caches of nearby camera records; "
                 "power: draw the same number in proportion to the VPLs' power, with no records "
                 "(the baseline importance caching is measured against)",
         .choices = {"records", "power"},
         .default_text = "records",
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_power_only = v == "power"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.ic_power_only ? "power" : "records";
         }},
        {.name = "connections",
         .flag = "--connections",
         .metavar = "path|ic",
         .type = OptionType::Choice,
         .help = "path: each eye vertex connects to every vertex of one light path; ic: to "
                 "light vertices drawn from importance caches (--connection-samples per "
                 "technique) over the vertices of the first --ic-light-paths light paths, MIS "
                 "weights unchanged",
         .choices = {"path", "ic"},
         .default_text = "path",
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_connections = v == "ic"; },
         .format = [](const RenderSettings& s) -> std::string {
             return s.ic_connections ? "ic" : "path";
         }},
        {.name = "ic_light_paths",
         .flag = "--ic-light-paths",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "light paths per iteration whose vertices the importance caches of ic "
                 "connections cover (one shadow ray per record and vertex)",
         .min = 1,
         .max = 1000000,
         .default_text = "64",
         .effective_with = {{"connections", "ic"}},
         .apply = [](RenderSettings& s, const std::string& v) { s.ic_light_paths = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.ic_light_paths); }},
        {.name = "connection_samples",
         .flag = "--connection-samples",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "light vertices drawn per technique (full, unoccluded, bounded, conservative) "
                 "at each eye vertex by ic connections: 4 N connections",
         .min = 1,
         .max = 4096,
         .default_text = "1",
         .effective_with = {{"connections", "ic"}},
         .apply = [](RenderSettings& s, const std::string& v) { s.connection_samples = to_int(v); },
         .format = [](const RenderSettings& s) { return std::to_string(s.connection_samples); }},
        // Adaptive sampling (docs/reference/adaptive-sampling.md): read by the algorithms whose
        // eye pass can skip a pixel (Integrator::takes_active_pixels).
        {.name = "adaptive",
         .flag = "--adaptive",
         .metavar = "T",
         .type = OptionType::Real,
         .help = "adaptive sampling: a pixel stops taking iterations once its noise per "
                 "iteration, sigma / (iterations x image mean), is at most T (sigma: the "
                 "standard deviation of its brightness R+G+B from odd/even halves, over its 3x3 "
                 "neighbourhood), i.e. after about sigma / (T x image mean) iterations; the "
                 "render stops when no pixel is left (0 = off, every pixel every iteration)",
         .min = 0,
         .max = 1,
         .default_text = "0",
         .apply = [](RenderSettings& s, const std::string& v) { s.adaptive = to_real(v); },
         .format = [](const RenderSettings& s) { return format_real(s.adaptive); }},
        {.name = "adaptive_min_iterations",
         .flag = "--adaptive-min-iterations",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "adaptive sampling: iterations every pixel takes before the first decision",
         .min = 2,
         .max = 1000000,
         .default_text = "16",
         .effective_with = {{"adaptive", "0.05"}},
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.adaptive_min_iterations = uint64_t(to_int(v)); },
         .format =
             [](const RenderSettings& s) { return std::to_string(s.adaptive_min_iterations); }},
        {.name = "adaptive_round",
         .flag = "--adaptive-round",
         .metavar = "N",
         .type = OptionType::Integer,
         .help = "adaptive sampling: iterations between two choices of the active pixels",
         .min = 1,
         .max = 1000000,
         .default_text = "8",
         .effective_with = {{"adaptive", "0.05"}},
         .apply = [](RenderSettings& s,
                     const std::string& v) { s.adaptive_round = uint64_t(to_int(v)); },
         .format = [](const RenderSettings& s) { return std::to_string(s.adaptive_round); }},
        {.name = "layers",
         .flag = "--layers",
         .metavar = "none|techniques|st|variance",
         .type = OptionType::Choice,
         .help = "extra EXR layers: techniques (connection and merging parts), st (one per "
                 "(s, t) technique, paths of up to 6 vertices), variance (each pixel's "
                 "estimated variance and the odd and even half images)",
         .choices = {"none", "techniques", "st", "variance"},
         .default_text = "none",
         .every_algorithm = true,
         .apply =
             [](RenderSettings& s, const std::string& v) {
                 s.layers = v == "techniques" ? LayerMode::Techniques
                            : v == "st"       ? LayerMode::PathVertices
                            : v == "variance" ? LayerMode::Variance
                                              : LayerMode::None;
             },
         .format = [](const RenderSettings& s) -> std::string {
             return s.layers == LayerMode::Techniques     ? "techniques"
                    : s.layers == LayerMode::PathVertices ? "st"
                    : s.layers == LayerMode::Variance     ? "variance"
                                                          : "none";
         }},
    };
    return rows;
}
#pragma GCC diagnostic pop

std::string join(const std::vector<std::string>& items, const char* separator) {
    std::string out;
    for (const std::string& s : items) out += (out.empty() ? "" : separator) + s;
    return out;
}

std::string range_text(const RenderOption& o) {
    std::string lo =
        o.type == OptionType::Real ? format_real(o.min) : std::to_string(int64_t(o.min));
    std::string hi =
        o.type == OptionType::Real ? format_real(o.max) : std::to_string(int64_t(o.max));
    return (o.min_exclusive ? "(" : "[") + lo + ", " + hi + "]";
}

}  // namespace

const std::vector<RenderOption>& render_options() {
    return table();
}

const RenderOption* find_render_option(std::string_view name) {
    for (const RenderOption& o : table())
        if (o.name == name) return &o;
    return nullptr;
}

std::string render_option_names() {
    std::vector<std::string> names;
    for (const RenderOption& o : table()) names.push_back(o.name);
    return join(names, ", ");
}

std::string format_real(double value) {
    char buffer[64];
    auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
    return ec == std::errc() ? std::string(buffer, end) : std::to_string(value);
}

namespace {

// What an option accepts, for error messages: "a number in (0, 1]", "one of on, off", ...
std::string expectation(const RenderOption& o) {
    switch (o.type) {
        case OptionType::Unsigned:
            return "an unsigned integer";
        case OptionType::Integer:
            return "an integer in " + range_text(o);
        case OptionType::Real:
            return "a number in " + range_text(o);
        case OptionType::Choice:
            return "one of " + join(o.choices, ", ");
    }
    return "a valid value";
}

// The canonical text of a valid value; nullopt for anything else (a parse error included).
std::optional<std::string> canonical_or_nothing(const RenderOption& o, const std::string& text) {
    try {
        switch (o.type) {
            case OptionType::Unsigned:
                return std::to_string(parse_number<uint64_t>("", text));
            case OptionType::Integer: {
                const int64_t v = parse_number<int64_t>("", text);
                if (double(v) < o.min || double(v) > o.max) return std::nullopt;
                return std::to_string(v);
            }
            case OptionType::Real: {
                const double v = parse_number<double>("", text);
                if (v < o.min || (o.min_exclusive && v == o.min) || v > o.max) return std::nullopt;
                return format_real(v);
            }
            case OptionType::Choice:
                for (const std::string& c : o.choices)
                    if (c == text) return c;
                return std::nullopt;
        }
    } catch (const UsageError&) {
    }
    return std::nullopt;
}

}  // namespace

std::string canonical_option_value(const RenderOption& o, const std::string& text) {
    if (std::optional<std::string> value = canonical_or_nothing(o, text)) return *value;
    throw std::invalid_argument("option " + o.name + " (" + o.flag + ") expects " + expectation(o) +
                                ", got \"" + text.substr(0, 64) + "\"");
}

RenderSettings resolve_render_settings(const std::string& algorithm, const OptionMap& options,
                                       const SceneSettings& scene) {
    const Algorithm& a = find_algorithm_or_throw(algorithm);
    RenderSettings settings;
    settings.algorithm = a.name;
    settings.max_depth = scene.max_depth;
    settings.rr_depth = scene.rr_depth;
    for (const auto& [name, value] : options) {
        const RenderOption* o = find_render_option(name);
        if (!o)
            throw std::invalid_argument("unknown option \"" + name.substr(0, 64) +
                                        "\" (options: " + render_option_names() + ")");
        if (!algorithm_reads(a, *o))
            throw std::invalid_argument("option " + name + " (" + o->flag +
                                        ") is not read by algorithm " + a.name + " (read by " +
                                        algorithms_reading(*o) + ")");
        o->apply(settings, canonical_option_value(*o, value));
    }
    return settings;
}

OptionMap render_settings_options(const RenderSettings& settings) {
    const Algorithm& a = find_algorithm_or_throw(settings.algorithm);
    OptionMap out;
    for (const RenderOption& o : table())
        if (algorithm_reads(a, o)) out[o.name] = o.format(settings);
    return out;
}

std::map<std::string, std::string> render_settings_metadata(const RenderSettings& settings) {
    std::map<std::string, std::string> out = {{"render:algorithm", settings.algorithm}};
    for (const auto& [name, value] : render_settings_options(settings))
        out["render:" + name] = value;
    return out;
}

void add_render_options(ArgumentParser& parser, OptionMap& options) {
    for (const RenderOption& o : table()) {
        std::string help =
            o.help + " (default " + o.default_text + "; " +
            (o.every_algorithm ? std::string("every algorithm") : algorithms_reading(o)) + ")";
        for (const auto& [name, value] : o.effective_with)
            help += "; has an effect only with " + find_render_option(name)->flag + " set";
        parser.value({o.flag}, o.metavar, help, [&options, &o](const std::string& v) {
            try {
                options[o.name] = canonical_option_value(o, v);
            } catch (const std::invalid_argument& e) {
                throw UsageError(e.what());
            }
        });
        if (!o.negated_flag.empty())
            parser.flag({o.negated_flag}, "same as " + o.flag + " " + o.negated_value,
                        [&options, &o] { options[o.name] = o.negated_value; });
    }
}

std::string render_tables_json() {
    nlohmann::json out;
    out["algorithms"] = nlohmann::json::array();
    for (const Algorithm& a : algorithms()) {
        nlohmann::json options = nlohmann::json::array();
        for (const RenderOption& o : table())
            if (algorithm_reads(a, o)) options.push_back(o.name);
        nlohmann::json variants = nlohmann::json::array();
        for (const auto& v : a.variants) variants.push_back(v);
        out["algorithms"].push_back({{"name", a.name},
                                     {"aliases", a.aliases},
                                     {"pbrt_integrators", a.pbrt_integrators},
                                     {"description", a.description},
                                     {"homogeneous_media", a.support.homogeneous_media},
                                     {"grid_media", a.support.grid_media},
                                     {"emissive_media", a.support.emissive_media},
                                     {"bounded_emissive_media", a.support.bounded_emissive_media},
                                     {"physically_based", a.physically_based},
                                     {"options", options},
                                     {"variants", variants},
                                     {"benchmarks", a.benchmarks}});
    }
    out["options"] = nlohmann::json::array();
    for (const RenderOption& o : table()) {
        static const char* kTypes[] = {"integer", "unsigned", "real", "choice"};
        std::vector<std::string> read_by;
        for (const Algorithm& a : algorithms())
            if (algorithm_reads(a, o)) read_by.push_back(a.name);
        out["options"].push_back({{"name", o.name},
                                  {"flag", o.flag},
                                  {"type", kTypes[int(o.type)]},
                                  {"help", o.help},
                                  {"default", o.default_text},
                                  {"min", o.min},
                                  {"max", o.max},
                                  {"min_exclusive", o.min_exclusive},
                                  {"choices", o.choices},
                                  {"negated_flag", o.negated_flag},
                                  {"every_algorithm", o.every_algorithm},
                                  {"effective_with", o.effective_with},
                                  {"read_by", read_by}});
    }
    return out.dump(2) + "\n";
}

}  // namespace render
