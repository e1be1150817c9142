// `client submit`: its options, the scene's bundle (every frame's files, hashed once), the
// upload of what the server lacks, and the SubmitJob request.

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "client/bundle.h"
#include "client/commands.h"
#include "client/frames.h"
#include "core/render/job_options.h"

namespace render::service {
namespace {

namespace fs = std::filesystem;

// SubmitJob's deadline for an animation: the server loads every frame's scene.
constexpr double kAnimationSubmitTimeout = 600.0;

struct SubmitOptions {
    std::string scene;
    render::JobOptions job;  // what `render` takes too: algorithm, stop, film, defines, options
    int priority = 0;
    std::string name;
    bool wait = false;
    std::string out;
    std::string frames;       // --frames A:B
    std::string frames_file;  // --frames-file F
};

render::ArgumentParser submit_parser(SubmitOptions& o) {
    using render::UsageError;
    render::ArgumentParser p;
    render::add_job_options(p, o.job);
    p.value({"--priority"}, "P", "higher runs first (default 0)",
            [&](const std::string& v) { o.priority = render::parse_number<int>("--priority", v); });
    p.value({"--name"}, "NAME", "job name (default: the scene file's name)",
            [&](const std::string& v) { o.name = v; });
    p.flag({"--wait"}, "show progress until the job ends (as `watch`)", [&] { o.wait = true; });
    p.value({"--out", "-o"}, "FILE.exr|DIR",
            "wait, then fetch the result as `fetch --out` does: FILE.exr for a single frame, "
            "DIR for every frame of an animation",
            [&](const std::string& v) { o.out = v; });
    p.value({"--frames"}, "A:B",
            "an animation: one job with the frames A, A+1, ..., B (both included, at most 1000); "
            "in -D values {frame} is the frame number, {frame:04} the number zero-padded to 4 "
            "digits",
            [&](const std::string& v) { o.frames = v; });
    p.value({"--frames-file"}, "F",
            "an animation: one frame per line of F, each line name=value defines separated by "
            "spaces ('-' alone: no overrides; blank lines and # comments skipped)",
            [&](const std::string& v) { o.frames_file = v; });
    p.positional([&](const std::string& v) {
        if (!o.scene.empty()) throw UsageError("submit: more than one scene file given");
        o.scene = v;
    });
    return p;
}

SubmitOptions parse_submit(const std::vector<std::string>& args) {
    SubmitOptions o;
    submit_parser(o).parse(args);
    if (o.scene.empty()) usage_error("submit: no scene file given");
    if (!o.frames.empty() && !o.frames_file.empty())
        usage_error("submit: give --frames or --frames-file, not both");
    if (o.frames.empty())
        for (const auto& [name, value] : o.job.defines)
            if (has_frame_placeholder(value))
                usage_error("submit: -D " + name + "=" + value +
                            " has a {frame} placeholder, which needs --frames A:B");
    return o;
}

// The request's settings for the job options (the server checks and completes them).
v1::RenderSettings request_settings(const render::JobOptions& job) {
    v1::RenderSettings s;
    s.set_algorithm(job.algorithm);
    if (job.iterations) s.set_iterations(*job.iterations);
    if (job.seconds) s.set_time_budget_seconds(*job.seconds);
    if (job.target_error) s.set_target_error(*job.target_error);
    s.set_width(uint32_t(job.width));
    s.set_height(uint32_t(job.height));
    for (const auto& [name, value] : job.defines) (*s.mutable_defines())[name] = value;
    for (const auto& [name, value] : job.options) (*s.mutable_options())[name] = value;
    return s;
}

void upload(const Connection& c, const BundleEntry& entry) {
    std::ifstream in(entry.absolute, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + entry.absolute.string());
    grpc::ClientContext context;
    c.prepare(context, 600.0);
    v1::BundleFile reply;
    std::unique_ptr<grpc::ClientWriter<v1::AssetChunk>> writer =
        c.stub->UploadAsset(&context, &reply);
    std::string buffer(kMaxChunkBytes, '\0');
    bool first = true, ok = true;
    while (ok) {
        in.read(buffer.data(), std::streamsize(buffer.size()));
        std::streamsize n = in.gcount();
        if (n <= 0 && !first) break;
        v1::AssetChunk chunk;
        if (first) {
            chunk.set_sha256(entry.sha256);
            chunk.set_size(entry.size);
        }
        chunk.set_data(buffer.data(), size_t(std::max<std::streamsize>(n, 0)));
        ok = writer->Write(chunk);
        first = false;
        if (n < std::streamsize(buffer.size())) break;
    }
    if (ok) writer->WritesDone();
    grpc::Status status = writer->Finish();
    if (!status.ok()) throw RpcFailure("UploadAsset " + entry.path, status);
}

}  // namespace

std::string submit_options_help() {
    SubmitOptions unused;
    return submit_parser(unused).help();
}

int submit(const Connection& c, const std::vector<std::string>& args) {
    SubmitOptions o = parse_submit(args);
    // An animation: each frame's overrides. The job's defines are the -D without {frame}.
    std::vector<Defines> frames;
    if (!o.frames.empty()) {
        frames = range_frames(parse_frame_range(o.frames), o.job.defines);
        if (frames.front().empty())
            std::fprintf(stderr,
                         "client: note: no -D value has a {frame} placeholder: the %zu frames "
                         "differ only in their noise\n",
                         frames.size());
        for (auto it = o.job.defines.begin(); it != o.job.defines.end();)
            it = has_frame_placeholder(it->second) ? o.job.defines.erase(it) : std::next(it);
    } else if (!o.frames_file.empty()) {
        frames = read_frames_file(o.frames_file);
    }
    // Refuse an --out that does not fit the job before submitting it.
    if (!o.out.empty()) check_output(o.out, uint32_t(std::max<size_t>(1, frames.size())));
    // The files of every frame (a define may name a file, e.g. a mesh per frame), hashed once.
    SceneBundleInfo bundle = collect_bundle(o.scene, o.job.defines, false);
    {
        std::set<Defines> seen{{}};
        std::set<std::string> paths;
        for (const BundleEntry& e : bundle.files) paths.insert(e.path);
        for (size_t i = 0; i < frames.size(); ++i) {
            if (!seen.insert(frames[i]).second) continue;
            Defines defines = o.job.defines;
            for (const auto& [k, v] : frames[i]) defines[k] = v;
            SceneBundleInfo more;
            try {
                more = collect_bundle(o.scene, defines, false);
            } catch (const std::exception& e) {
                throw std::runtime_error("frame " + std::to_string(i) + " (" +
                                         format_defines(frames[i]) + "): " + e.what());
            }
            if (i == 0) {
                bundle.integrator = more.integrator;
                bundle.sample_count = more.sample_count;
            }
            for (BundleEntry& e : more.files)
                if (paths.insert(e.path).second) bundle.files.push_back(std::move(e));
        }
        hash_bundle(bundle);
    }
    v1::RenderSettings s = request_settings(o.job);
    // Without --algo the server takes the scene's integrator (Mitsuba's "path" is "pt").
    if (!o.job.iterations && !o.job.seconds) {
        if (!bundle.sample_count)
            usage_error("submit: the scene has no sample_count; give --iterations or --time");
        s.set_iterations(*bundle.sample_count);
    }
    uint64_t total = 0;
    for (const BundleEntry& e : bundle.files) total += e.size;

    // Upload what the server does not have yet.
    v1::HasAssetsRequest has_request;
    for (const BundleEntry& e : bundle.files) has_request.add_sha256(e.sha256);
    v1::HasAssetsReply has_reply;
    {
        grpc::ClientContext context;
        c.prepare(context);
        grpc::Status status = c.stub->HasAssets(&context, has_request, &has_reply);
        if (!status.ok()) throw RpcFailure("HasAssets", status);
    }
    std::set<std::string> missing(has_reply.missing().begin(), has_reply.missing().end());
    uint64_t uploaded = 0;
    size_t uploaded_files = 0;
    for (const BundleEntry& e : bundle.files) {
        if (!missing.count(e.sha256)) continue;
        upload(c, e);
        missing.erase(e.sha256);  // two paths with the same content: upload once
        uploaded += e.size;
        ++uploaded_files;
    }
    std::fprintf(stderr, "client: %s: %zu files (%.1f KiB), uploaded %zu (%.1f KiB)\n",
                 o.scene.c_str(), bundle.files.size(), total / 1024.0, uploaded_files,
                 uploaded / 1024.0);

    v1::SubmitJobRequest request;
    request.set_name(o.name.empty() ? fs::path(o.scene).filename().string() : o.name);
    request.set_priority(o.priority);
    *request.mutable_settings() = s;
    for (const Defines& frame : frames) {
        v1::FrameOverride* f = request.add_frames();
        for (const auto& [k, v] : frame) (*f->mutable_defines())[k] = v;
    }
    v1::SceneBundle* b = request.mutable_bundle();
    b->set_scene_path(bundle.scene_path);
    for (const BundleEntry& e : bundle.files) {
        v1::BundleFile* f = b->add_files();
        f->set_path(e.path);
        f->set_sha256(e.sha256);
        f->set_size(e.size);
    }
    v1::Job job;
    {
        grpc::ClientContext context;
        // The server loads every frame's scene before it answers (within its
        // --submit-validation-seconds, 120 s by default).
        c.prepare(context, frames.size() > 1 ? kAnimationSubmitTimeout : kRpcTimeout);
        grpc::Status status = c.stub->SubmitJob(&context, request, &job);
        if (!status.ok()) throw RpcFailure("SubmitJob", status);
    }
    std::printf("%s\n", job.id().c_str());
    std::fflush(stdout);
    if (!o.wait && o.out.empty()) return 0;
    int rc = watch(c, job.id());
    if (rc != 0 || o.out.empty()) return rc;
    return fetch_output(c, job.id(), uint32_t(job.frames_size()), std::nullopt, false, o.out);
}

}  // namespace render::service
