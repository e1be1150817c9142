// `render`: renders a scene file to an OpenEXR image on this machine, or compares two images.
// Its options come from the algorithm table and the render options (core/render/): `render
// --help` lists them.

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/image/exr_io.h"
#include "core/image/metrics.h"
#include "core/render/algorithms.h"
#include "core/render/image_metadata.h"
#include "core/render/iteration_memory.h"
#include "core/render/job_limits.h"
#include "core/render/job_options.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/arguments.h"
#include "core/util/format_seconds.h"

namespace {

using namespace render;
using Clock = std::chrono::steady_clock;

// Full-frame sums (3 doubles per pixel) `render` holds: the accumulated sum and odd sum, the
// renderer's iteration image, and the averaged image written at the end.
constexpr uint64_t kRenderFilmBuffers = 4;

struct Options {
    std::string scene;
    std::string out;
    std::string png;
    JobOptions job;  // algorithm, iterations, time, film, defines, render options
    int threads = 0;
    uint32_t frame = 0;       // the frame index of the random numbers (a service job's frame)
    uint64_t max_memory = 0;  // 0: no limit
    bool help = false;
    bool describe = false;
    bool target_error_per_pixel = false;  // --target-error bounds every pixel's estimate
};

ArgumentParser make_parser(Options& o) {
    ArgumentParser p;
    p.value({"--out", "-o"}, "FILE.exr", "output image (required)",
            [&](const std::string& v) { o.out = v; });
    add_job_options(p, o.job);
    p.value({"--threads"}, "T", "worker threads (default: all cores; never changes the image)",
            [&](const std::string& v) {
                o.threads = parse_number<int>("--threads", v);
                if (o.threads < 0) throw UsageError("--threads must be >= 0");
            });
    p.value({"--max-memory"}, "SIZE",
            "refuse, before rendering, a scene whose estimated memory (its files, meshes, "
            "grids and images, the film and the algorithm's working memory per iteration) "
            "exceeds SIZE, as a worker's --max-memory does (K, M, G or T suffix; default: no "
            "limit)",
            [&](const std::string& v) { o.max_memory = parse_size_flag("--max-memory", v); });
    p.value({"--frame"}, "F",
            "render as frame F of a job (an animation's frame index, from 0, seeds the random "
            "numbers with the seed); with that frame's -D defines the image equals the "
            "service's frame F (default 0)",
            [&](const std::string& v) { o.frame = parse_number<uint32_t>("--frame", v); });
    p.flag({"--target-error-per-pixel"},
           "--target-error E bounds every pixel's estimated relative error (the RMS of the "
           "relative errors of its brightness R+G+B over its 3x3 neighbourhood, odd/even "
           "iterations) instead of the image's (render only; the service takes the image's)",
           [&] { o.target_error_per_pixel = true; });
    p.value({"--png"}, "FILE.png", "also write a tone-mapped sRGB preview",
            [&](const std::string& v) { o.png = v; });
    p.flag({"--help", "-h"}, "this text", [&] { o.help = true; });
    p.flag({"--describe-options"}, "print the algorithm and option tables as JSON and exit",
           [&] { o.describe = true; });
    p.positional([&](const std::string& v) {
        if (!o.scene.empty()) throw UsageError("more than one scene file given");
        o.scene = v;
    });
    return p;
}

std::string usage() {
    Options unused;
    return "usage:\n"
           "  render SCENE.xml|SCENE.pbrt --out FILE.exr [options]\n"
           "  render --compare TEST.exr REFERENCE.exr\n\n"
           "options:\n" +
           make_parser(unused).help() + "\nalgorithms (--algo):\n" + algorithms_help();
}

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "render: " << message << "\n\n" << usage();
    std::exit(2);
}

Options parse_options(int argc, char** argv) {
    Options o;
    make_parser(o).parse(argc, argv);
    if (o.help) {
        std::cout << usage();
        std::exit(0);
    }
    if (o.describe) {
        std::cout << render_tables_json();
        std::exit(0);
    }
    if (o.scene.empty()) throw UsageError("no scene file given");
    if (o.out.empty()) throw UsageError("--out FILE.exr is required");
    if (o.target_error_per_pixel && !o.job.target_error)
        throw UsageError("--target-error-per-pixel needs --target-error E");
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
    // Charged by the loaders, then with the film and the algorithm's working memory, before
    // anything is rendered; without --max-memory it only counts.
    SceneMemoryBudget budget(o.max_memory, "render --max-memory " + format_bytes(o.max_memory));
    std::unique_ptr<Scene> scene = load_scene(o.scene, o.job.defines);
    if (o.job.width > 0)
        scene->set_camera(scene->camera().with_resolution(o.job.width, o.job.height));
    double load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    // The same resolution as the service's worker: defaults, the scene's values, the options.
    RenderSettings settings = resolve_render_settings(
        job_algorithm(o.job.algorithm, scene->settings.integrator), o.job.options, scene->settings);
    settings.threads = o.threads;
    check_algorithm_supports_scene(settings, *scene);
    const uint64_t scene_bytes = budget.charged();
    const uint64_t film_w = uint64_t(scene->camera().width()),
                   film_h = uint64_t(scene->camera().height());
    budget.charge(film_memory_bytes(film_w, film_h, kRenderFilmBuffers),
                  "the film (" + std::to_string(film_w) + " x " + std::to_string(film_h) + ")");
    const IterationMemoryEstimate working =
        estimate_iteration_memory(settings, film_w, film_h, o.threads);
    budget.charge(working.bytes, working.what);
    std::fprintf(stderr, "render: memory estimate %s (scene %s, film %s, per iteration %s)\n",
                 format_bytes(budget.charged()).c_str(), format_bytes(scene_bytes).c_str(),
                 format_bytes(film_memory_bytes(film_w, film_h, kRenderFilmBuffers)).c_str(),
                 format_bytes(working.bytes).c_str());

    std::optional<uint64_t> total = o.job.iterations;
    if (!total && !o.job.seconds) total = uint64_t(std::max(1, scene->settings.sample_count));
    const int width = scene->camera().width(), height = scene->camera().height();
    std::fprintf(stderr, "render: %s, %dx%d, %s, max_depth %d, %s (scene loaded in %.2fs)\n",
                 o.scene.c_str(), width, height, settings.algorithm.c_str(), settings.max_depth,
                 total ? (std::to_string(*total) + " iterations").c_str() : "time budget",
                 load_seconds);

    // The renderer (its integrator's light vertices and grids, the iteration image) is freed
    // before the image is averaged and written, so that those do not add to its peak memory.
    auto renderer = std::make_unique<IterationRenderer>(*scene, settings, o.frame);
    IterationResult accumulated = renderer->empty_result();
    Progress progress(total, o.job.seconds);
    auto t0 = Clock::now();
    double elapsed = 0;
    // One iteration per call: the sum over [1, N+1) equals one big call, and it lets the
    // progress bar and the time budget act between iterations.
    // Adaptive sampling (docs/reference/adaptive-sampling.md) also stops when every pixel has
    // converged: its threshold is then a per-pixel target error.
    const bool adaptive = settings.adaptive > 0;
    bool converged = false;
    for (uint64_t i = 1;; ++i) {
        if (total && i > *total) break;
        if (o.job.seconds && elapsed >= *o.job.seconds && i > 1) break;
        if (adaptive && renderer->adaptive_active_pixels(accumulated) == 0) {
            converged = true;
            break;
        }
        if (adaptive)
            renderer->add_adaptive(IterationRange{i, i + 1}, accumulated);
        else
            renderer->add(IterationRange{i, i + 1}, accumulated);
        elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
        progress.update(accumulated.count, elapsed);
        if (o.job.target_error && accumulated.count >= kMinTargetErrorIterations &&
            (o.target_error_per_pixel
                 ? max_pixel_relative_error(accumulated)
                 : estimate_relative_error(accumulated)) <= *o.job.target_error)
            break;
    }
    progress.finish();
    renderer.reset();

    Image image = mean_image(accumulated);
    if (adaptive) {
        uint64_t samples = 0;
        for (uint64_t n : accumulated.adaptive.count) samples += n;
        std::fprintf(
            stderr, "render: adaptive, %.2f iterations per pixel on average (%llu iterations)%s\n",
            double(samples) / double(std::max<size_t>(1, accumulated.adaptive.count.size())),
            (unsigned long long)accumulated.count,
            converged ? ", every pixel below the threshold" : "");
    }
    const double error = estimate_relative_error(accumulated);
    RenderedImageFacts facts{
        o.scene, accumulated.count, elapsed, error, accumulated.stats.non_finite, o.job.defines};
    facts.invalid_rays = accumulated.stats.invalid_rays;
    facts.vpl_candidates = accumulated.stats.vpl_candidates;
    facts.vpl_accepted = accumulated.stats.vpl_accepted;
    facts.target_error = o.job.target_error.value_or(0.0);
    const auto metadata = image_metadata(settings, facts);
    write_exr(o.out, image, metadata, output_layers(accumulated));
    if (!o.png.empty()) write_png_preview(o.png, image);

    double samples_per_s = elapsed > 0 ? accumulated.stats.samples / elapsed : 0;
    double rays_per_s = elapsed > 0 ? accumulated.stats.rays / elapsed : 0;
    std::printf(
        "%llu iterations in %.2f s: %.3g samples/s, %.3g rays/s, estimated relative error "
        "%.3g, %llu non-finite samples dropped -> %s\n",
        (unsigned long long)accumulated.count, elapsed, samples_per_s, rays_per_s, error,
        (unsigned long long)accumulated.stats.non_finite, o.out.c_str());
    if (accumulated.stats.invalid_rays > 0)
        std::printf(
            "%llu rays were not traced: not finite or beyond the scene limits (taken as "
            "misses)\n",
            (unsigned long long)accumulated.stats.invalid_rays);
    if (accumulated.stats.vpl_candidates > 0)
        std::printf("VPLs: %.1f candidates per iteration, %.1f %% accepted (importance-driven)\n",
                    double(accumulated.stats.vpl_candidates) / double(accumulated.count),
                    100.0 * double(accumulated.stats.vpl_accepted) /
                        double(accumulated.stats.vpl_candidates));
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        if (argc >= 2 && std::string(argv[1]) == "--compare") {
            if (argc != 4) usage_error("--compare needs exactly two images");
            return compare(argv[2], argv[3]);
        }
        return render_scene(parse_options(argc, argv));
    } catch (const UsageError& e) {
        usage_error(e.what());
    } catch (const SceneError& e) {
        std::cerr << "render: scene error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "render: error: " << e.what() << "\n";
        return 1;
    }
}
