#include "core/render/job_options.h"

#include "core/render/job_limits.h"
#include "core/util/arguments.h"

namespace render {

void add_job_options(ArgumentParser& p, JobOptions& job) {
    p.value({"--algo"}, "NAME", "light-transport algorithm (default: the scene's integrator)",
            [&job](const std::string& v) { job.algorithm = v; });
    p.value({"--iterations", "--spp"}, "N",
            "progressive iterations per frame, one sample per pixel each (default: the scene's "
            "sampler sample_count)",
            [&job](const std::string& v) { job.iterations = parse_iterations("--iterations", v); });
    p.value({"--time"}, "S",
            "time budget per frame in seconds (with --iterations: whichever comes first)",
            [&job](const std::string& v) { job.seconds = parse_time_budget("--time", v); });
    p.value({"--target-error"}, "E",
            "stop a frame once its estimated relative error (odd/even iterations, relative L2 "
            "norm over all pixels) is at most E, after at least 4 iterations; --iterations "
            "(default: the scene's sample_count) and --time still cap it",
            [&job](const std::string& v) {
                job.target_error = parse_target_error("--target-error", v);
            });
    p.value({"--resolution"}, "WxH", "override the film resolution", [&job](const std::string& v) {
        std::tie(job.width, job.height) = parse_resolution("--resolution", v, kMaxFilmResolution);
    });
    p.value({"-D"}, "name=value", "override a <default> of the scene file (repeatable)",
            [&job](const std::string& v) {
                auto [name, value] = parse_define("-D", v);
                job.defines[name] = value;
            });
    add_render_options(p, job.options);
}

}  // namespace render
