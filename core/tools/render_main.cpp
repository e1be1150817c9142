// `render`: renders a scene file to an OpenEXR image on this machine, or compares two images.
//
//   render SCENE.xml [--algo pt] [--iterations N] [--time S] [--threads T] [--seed S]
//          [--resolution WxH] [--max-depth D] [-D name=value ...] [--png FILE.png]
//          --out FILE.exr
//   render --compare TEST.exr REFERENCE.exr

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/image/exr_io.h"
#include "core/image/metrics.h"
#include "core/integrators/integrator.h"
#include "core/render/render_iterations.h"
#include "core/scene/error.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/format_seconds.h"

namespace {

using namespace render;
using Clock = std::chrono::steady_clock;

constexpr const char* kUsage = R"(usage:
  render SCENE.xml --out FILE.exr [options]
  render --compare TEST.exr REFERENCE.exr

options:
  --algo NAME          integrator: pt (path tracing, default), volpt (volumetric path
                       tracing, for scenes with media; "volpath" too), lt (light tracing),
                       bpt (bidirectional path tracing), ppm (progressive photon mapping),
                       bpm (bidirectional photon mapping), vcm (vertex connection and
                       merging), eyelight (debug shading)
  --iterations N       progressive iterations, one sample per pixel each
                       (default: the scene's sampler sample_count)
  --time S             stop after S seconds (with --iterations: whichever comes first)
  --threads T          worker threads (default: all cores; never changes the image)
  --seed S             random seed (default 0)
  --resolution WxH     override the film resolution
  --max-depth D        override the scene's max_depth (-1 = unbounded)
  -D name=value        override a <default> of the scene file (repeatable)
  --radius-factor F    initial merging radius / scene bounding-sphere radius (0.003)
  --alpha A            merging radius reduction, r_i = r_1 i^((A-1)/2), A in (0, 1] (0.75)
  --light-paths N      light paths per iteration (default: one per pixel)
  --mis power|balance  MIS heuristic of the bidirectional family (power)
  --no-equiangular     volpt: distance sampling only (no equi-angular sampling)
  --layers KIND        extra EXR layers: techniques (connection and merging parts),
                       st (one image per (s, t) technique, paths of up to 6 vertices)
  --png FILE.png       also write a tone-mapped sRGB preview
  --out FILE.exr       output image (required)
)";

struct Options {
    std::string scene;
    std::string out;
    std::string png;
    std::string algorithm;
    std::optional<uint64_t> iterations;
    std::optional<double> seconds;
    int threads = 0;
    uint64_t seed = 0;
    int width = 0, height = 0;
    std::optional<int> max_depth;
    std::map<std::string, std::string> defines;
    double radius_factor = RenderSettings().radius_factor;
    double alpha = RenderSettings().alpha;
    uint64_t light_paths = 0;
    bool equiangular = true;
    int mis_power = 2;
    LayerMode layers = LayerMode::None;
};

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "render: " << message << "\n\n" << kUsage;
    std::exit(2);
}

template <typename T>
T parse_number(const std::string& flag, const std::string& text) {
    std::istringstream in(text);
    T value{};
    if (!(in >> value) || !in.eof()) usage_error(flag + " expects a number, got \"" + text + "\"");
    return value;
}

Options parse_options(int argc, char** argv) {
    Options o;
    std::vector<std::string> args(argv + 1, argv + argc);
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= args.size()) usage_error(a + " needs a value");
            return args[++i];
        };
        if (a == "--out" || a == "-o") {
            o.out = value();
        } else if (a == "--png") {
            o.png = value();
        } else if (a == "--algo") {
            o.algorithm = value();
        } else if (a == "--iterations" || a == "--spp") {
            int64_t n = parse_number<int64_t>(a, value());
            if (n < 1) usage_error(a + " must be at least 1");
            o.iterations = uint64_t(n);
        } else if (a == "--time") {
            double s = parse_number<double>(a, value());
            if (!(s > 0)) usage_error("--time must be positive");
            o.seconds = s;
        } else if (a == "--threads") {
            o.threads = parse_number<int>(a, value());
            if (o.threads < 0) usage_error("--threads must be >= 0");
        } else if (a == "--seed") {
            o.seed = parse_number<uint64_t>(a, value());
        } else if (a == "--radius-factor") {
            o.radius_factor = parse_number<double>(a, value());
            if (!(o.radius_factor > 0)) usage_error("--radius-factor must be positive");
        } else if (a == "--alpha") {
            o.alpha = parse_number<double>(a, value());
            if (!(o.alpha > 0 && o.alpha <= 1)) usage_error("--alpha must be in (0, 1]");
        } else if (a == "--light-paths") {
            int64_t n = parse_number<int64_t>(a, value());
            if (n < 1) usage_error("--light-paths must be at least 1");
            o.light_paths = uint64_t(n);
        } else if (a == "--no-equiangular") {
            o.equiangular = false;
        } else if (a == "--mis") {
            std::string v = value();
            if (v == "power")
                o.mis_power = 2;
            else if (v == "balance")
                o.mis_power = 1;
            else
                usage_error("--mis expects power or balance, got \"" + v + "\"");
        } else if (a == "--layers") {
            std::string v = value();
            if (v == "techniques")
                o.layers = LayerMode::Techniques;
            else if (v == "st")
                o.layers = LayerMode::PathVertices;
            else
                usage_error("--layers expects techniques or st, got \"" + v + "\"");
        } else if (a == "--max-depth") {
            o.max_depth = parse_number<int>(a, value());
        } else if (a == "--resolution") {
            std::string v = value();
            size_t x = v.find('x');
            if (x == std::string::npos) usage_error("--resolution expects WxH, got \"" + v + "\"");
            o.width = parse_number<int>(a, v.substr(0, x));
            o.height = parse_number<int>(a, v.substr(x + 1));
            if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
                usage_error("--resolution must be between 1x1 and 16384x16384");
        } else if (a == "-D" || (a.rfind("-D", 0) == 0 && a.size() > 2)) {
            std::string def = a == "-D" ? value() : a.substr(2);
            size_t eq = def.find('=');
            if (eq == std::string::npos || eq == 0) usage_error("-D expects name=value");
            o.defines[def.substr(0, eq)] = def.substr(eq + 1);
        } else if (a == "--help" || a == "-h") {
            std::cout << kUsage;
            std::exit(0);
        } else if (!a.empty() && a[0] == '-') {
            usage_error("unknown option " + a);
        } else if (o.scene.empty()) {
            o.scene = a;
        } else {
            usage_error("more than one scene file given");
        }
    }
    if (o.scene.empty()) usage_error("no scene file given");
    if (o.out.empty()) usage_error("--out FILE.exr is required");
    return o;
}

int compare(const std::string& test_file, const std::string& reference_file) {
    Image test = read_image(test_file), reference = read_image(reference_file);
    ImageComparison c = compare_images(test, reference);
    std::printf("%-16s %14s %14s %14s\n", "metric", "R", "G", "B");
    std::printf("%-16s %14.6g %14.6g %14.6g\n", "rmse", c.rmse[0], c.rmse[1], c.rmse[2]);
    std::printf("%-16s %14.6g %14.6g %14.6g\n", "relative_mse", c.relative_mse[0],
                c.relative_mse[1], c.relative_mse[2]);
    std::printf("%-16s %14.6g %14.6g %14.6g\n", "mean_difference", c.mean_difference[0],
                c.mean_difference[1], c.mean_difference[2]);
    std::printf("overall: rmse %.6g, relative_mse %.6g, non-finite pixels %zu\n", c.rmse_all,
                c.relative_mse_all, c.non_finite);
    return 0;
}

// A progress bar on a terminal; a plain line every 10% (or every 10 s) otherwise.
class Progress {
  public:
    Progress(std::optional<uint64_t> total, std::optional<double> budget)
        : total_(total), budget_(budget), tty_(isatty(STDERR_FILENO)) {}

    void update(uint64_t done, double elapsed) {
        double fraction = 0;
        if (total_) fraction = double(done) / double(*total_);
        if (budget_) fraction = std::max(fraction, elapsed / *budget_);
        fraction = std::min(fraction, 1.0);
        double eta = fraction > 0 ? elapsed * (1.0 - fraction) / fraction : 0;
        double rate = elapsed > 0 ? done / elapsed : 0;
        if (tty_) {
            if (elapsed - last_draw_ < 0.1 && fraction < 1.0) return;
            last_draw_ = elapsed;
            const int width = 30;
            int filled = int(fraction * width);
            std::fprintf(stderr, "\r[%s%s] %3d%%  %llu it  %.2f it/s  %s  ETA %s   ",
                         std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(),
                         int(fraction * 100), (unsigned long long)done, rate,
                         format_seconds(elapsed).c_str(), format_seconds(eta).c_str());
        } else {
            int decile = int(fraction * 10);
            if (decile <= last_decile_ && elapsed - last_draw_ < 10.0) return;
            last_decile_ = decile;
            last_draw_ = elapsed;
            std::fprintf(stderr, "progress: %3d%%  %llu iterations  %.2f it/s  %s  ETA %s\n",
                         int(fraction * 100), (unsigned long long)done, rate,
                         format_seconds(elapsed).c_str(), format_seconds(eta).c_str());
        }
    }
    void finish() {
        if (tty_) std::fprintf(stderr, "\n");
    }

  private:
    std::optional<uint64_t> total_;
    std::optional<double> budget_;
    bool tty_;
    double last_draw_ = -1;
    int last_decile_ = -1;
};

int render_scene(const Options& o) {
    auto t_load = Clock::now();
    std::unique_ptr<Scene> scene = load_scene(o.scene, o.defines);
    if (o.width > 0) scene->set_camera(scene->camera().with_resolution(o.width, o.height));
    double load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    RenderSettings settings;
    settings.algorithm = o.algorithm.empty() ? scene->settings.integrator : o.algorithm;
    settings.max_depth = o.max_depth ? *o.max_depth : scene->settings.max_depth;
    settings.rr_depth = scene->settings.rr_depth;
    settings.seed = o.seed;
    settings.threads = o.threads;
    settings.radius_factor = o.radius_factor;
    settings.alpha = o.alpha;
    settings.light_path_count = o.light_paths;
    settings.mis_power = o.mis_power;
    settings.equiangular = o.equiangular;
    settings.layers = o.layers;
    // Validate the algorithm before rendering anything.
    (void)make_integrator(settings);
    check_algorithm_supports_scene(settings.algorithm, *scene);

    std::optional<uint64_t> total = o.iterations;
    if (!total && !o.seconds) total = uint64_t(std::max(1, scene->settings.sample_count));
    const int width = scene->camera().width(), height = scene->camera().height();
    std::fprintf(stderr, "render: %s, %dx%d, %s, max_depth %d, %s (scene loaded in %.2fs)\n",
                 o.scene.c_str(), width, height, settings.algorithm.c_str(), settings.max_depth,
                 total ? (std::to_string(*total) + " iterations").c_str() : "time budget",
                 load_seconds);

    IterationResult accumulated;
    accumulated.sum = AccumulationBuffer(width, height);
    accumulated.odd_sum = AccumulationBuffer(width, height);
    accumulated.layers = TechniqueLayers(settings.layers, width, height);
    Progress progress(total, o.seconds);
    auto t0 = Clock::now();
    double elapsed = 0;
    // One iteration per call: the sum over [1, N+1) equals one big call, and it lets the
    // progress bar and the time budget act between iterations.
    for (uint64_t i = 1;; ++i) {
        if (total && i > *total) break;
        if (o.seconds && elapsed >= *o.seconds && i > 1) break;
        IterationResult r = render_iterations(*scene, settings, 0, IterationRange{i, i + 1});
        accumulated.sum.add(r.sum);
        accumulated.odd_sum.add(r.odd_sum);
        accumulated.count += r.count;
        accumulated.odd_count += r.odd_count;
        accumulated.stats += r.stats;
        accumulated.layers.add(r.layers);
        elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
        progress.update(accumulated.count, elapsed);
    }
    progress.finish();

    Image image = accumulated.sum.average(double(accumulated.count));
    double error = estimate_relative_error(accumulated);
    std::map<std::string, std::string> metadata = {
        {"render:scene", o.scene},
        {"render:algorithm", settings.algorithm},
        {"render:iterations", std::to_string(accumulated.count)},
        {"render:seconds", std::to_string(elapsed)},
        {"render:seed", std::to_string(settings.seed)},
        {"render:max_depth", std::to_string(settings.max_depth)},
        {"render:rr_depth", std::to_string(settings.rr_depth)},
        {"render:radius_factor", std::to_string(settings.radius_factor)},
        {"render:alpha", std::to_string(settings.alpha)},
        {"render:light_paths", std::to_string(settings.light_path_count)},
        {"render:mis", settings.mis_power == 1 ? "balance" : "power"},
        {"render:relative_error_estimate", std::to_string(error)},
        {"render:non_finite_samples_dropped", std::to_string(accumulated.stats.non_finite)},
    };
    for (const auto& [name, value] : o.defines) metadata["render:define:" + name] = value;
    std::vector<NamedLayer> layers;
    for (size_t i = 0; i < accumulated.layers.size(); ++i) {
        const AccumulationBuffer& buffer = accumulated.layers.buffer(i);
        bool any = false;
        for (double v : buffer.values()) any |= v != 0;
        if (any)  // techniques that never contributed are left out of the file
            layers.push_back(
                {accumulated.layers.name(i), buffer.average(double(accumulated.count))});
    }
    write_exr(o.out, image, metadata, layers);
    if (!o.png.empty()) write_png_preview(o.png, image);

    double samples_per_s = elapsed > 0 ? accumulated.stats.samples / elapsed : 0;
    double rays_per_s = elapsed > 0 ? accumulated.stats.rays / elapsed : 0;
    std::printf(
        "%llu iterations in %.2f s: %.3g samples/s, %.3g rays/s, estimated relative error "
        "%.3g, %llu non-finite samples dropped -> %s\n",
        (unsigned long long)accumulated.count, elapsed, samples_per_s, rays_per_s, error,
        (unsigned long long)accumulated.stats.non_finite, o.out.c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        if (argc >= 2 && std::strcmp(argv[1], "--compare") == 0) {
            if (argc != 4) usage_error("--compare needs exactly two images");
            return compare(argv[2], argv[3]);
        }
        return render_scene(parse_options(argc, argv));
    } catch (const SceneError& e) {
        std::cerr << "render: scene error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "render: error: " << e.what() << "\n";
        return 1;
    }
}
