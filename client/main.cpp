// `client`: the command line of the render service.
//
//   client [--server HOST:PORT] [--token T] [--tls-ca FILE [--tls-server-name NAME]] COMMAND ...
//   (see kUsage)

#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "client/bundle.h"
#include "client/frames.h"
#include "client/progress.h"
#include "core/base/memory_budget.h"
#include "core/render/algorithms.h"
#include "core/render/job_options.h"
#include "core/render/render_options.h"
#include "core/util/arguments.h"
#include "core/util/sha256.h"
#include "render.grpc.pb.h"
#include "service/process_setup.h"
#include "service/rpc.h"

namespace {

using namespace render::service;
namespace v1 = render::v1;
namespace fs = std::filesystem;

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

render::ArgumentParser submit_parser(SubmitOptions& o);

// Whether the channel is TLS: --tls-ca or env RENDER_TLS_CA.
bool tls_used(const std::string& tls_ca_flag) {
    return !flag_or_env(tls_ca_flag, "RENDER_TLS_CA").empty();
}

// A hint for a server that cannot be reached: a TLS mismatch shows up as UNAVAILABLE.
std::string connection_hint(const grpc::Status& status, bool tls) {
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE) return "";
    return tls ? "\nclient: with --tls-ca the server must serve TLS (--tls-cert/--tls-key) with a "
                 "certificate signed by that CA for the host of --server (or for "
                 "--tls-server-name)"
               : "\nclient: if the server serves TLS (--tls-cert/--tls-key), give --tls-ca FILE";
}

std::string usage() {
    SubmitOptions unused;
    return R"(usage:
  client [--server HOST:PORT] [--token T] [--tls-ca FILE] COMMAND ...

commands:
  submit SCENE.xml [options]   pack the scene and the files it references, upload what the
                               server lacks, submit a job and print its id
  watch JOB                    progress until the job ends; exit status 1 unless it is DONE
  fetch JOB [--frame F] [--preview] --out FILE.exr|DIR
                               download a frame's EXR (--preview: the current average);
                               --out DIR (a name not ending in .exr) without --frame
                               writes every frame as DIR/frame_0000.exr, frame_0001.exr, ...
                               (frame numbers are the job's frame indices, from 0); a job
                               of several frames needs --out DIR or --frame F
  cancel JOB                   cancel a job
  delete JOB                   delete a finished, failed or cancelled job: its results and the
                               assets no other job uses
  list                         all jobs
  status                       workers and queue
  bundle SCENE.xml [-D k=v]    list the files `submit` would upload, with their SHA-256
  hash FILE...                 print the SHA-256 of files (as the asset store names them)

global options:
  --server HOST:PORT           default: env RENDER_SERVER, else 127.0.0.1:50051
  --token T                    bearer token (default: env RENDER_TOKEN)
  --tls-ca FILE                connect with TLS, trusting the CA certificate(s) in FILE
                               (PEM; default: env RENDER_TLS_CA); without it the connection
                               is plaintext and a token is only sent to a loopback address
  --tls-server-name NAME       the name the server's certificate must carry, when it is not
                               the host of --server (default: env RENDER_TLS_SERVER_NAME)

submit options (the render options are those of `render`, with the same meaning):
)" + submit_parser(unused).help() +
           "\nalgorithms (--algo):\n" + render::algorithms_help() + R"(
Exit status: 0 on success, 1 on a failed call or job (the gRPC status is printed), 2 on
bad usage.
)";
}

constexpr double kRpcTimeout = 30.0;
// SubmitJob's deadline for an animation: the server loads every frame's scene.
constexpr double kAnimationSubmitTimeout = 600.0;

[[noreturn]] void usage_error(const std::string& message) {
    std::cerr << "client: " << message << "\n\n" << usage();
    std::exit(2);
}

struct RpcFailure : std::runtime_error {
    RpcFailure(const std::string& call, const grpc::Status& s)
        : std::runtime_error(call + " failed: " + describe(s)), status(s) {}
    grpc::Status status;
};

struct Connection {
    std::string address;
    std::string token;
    std::unique_ptr<v1::JobService::Stub> stub;

    void prepare(grpc::ClientContext& context, double timeout = kRpcTimeout) const {
        prepare_context(context, token, timeout);
    }
};

// ---------------------------------------------------------------------------------------------
// submit

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

int watch(const Connection& c, const std::string& job_id);
int fetch(const Connection& c, const std::string& job_id, uint32_t frame, bool preview,
          const std::string& out);

// What `fetch --out OUT` writes: OUT ending in .exr is one file, of --frame F or of the only
// frame of a single-frame job; any other OUT is a folder that receives frame_NNNN.exr for
// --frame F or else for every frame. Throws UsageError for a job of several frames with
// FILE.exr and no --frame, a folder that is a file, or a file that is a folder.
struct OutputPlan {
    bool folder = false;
    std::vector<uint32_t> frames;
};
OutputPlan output_plan(const std::string& out, uint32_t frame_count,
                       std::optional<uint32_t> frame) {
    std::string lower = out;
    for (char& ch : lower) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    OutputPlan plan;
    plan.folder = !(lower.size() > 4 && lower.substr(lower.size() - 4) == ".exr");
    std::error_code ec;
    if (plan.folder && fs::exists(out, ec) && !fs::is_directory(out, ec))
        throw render::UsageError("--out " + out +
                                 " is a file, not a folder (a single frame's "
                                 "file name ends in .exr)");
    if (!plan.folder && fs::is_directory(out, ec))
        throw render::UsageError("--out " + out + " is a folder; its name must not end in .exr");
    if (frame) {
        plan.frames = {*frame};
    } else if (plan.folder) {
        for (uint32_t i = 0; i < frame_count; ++i) plan.frames.push_back(i);
    } else if (frame_count > 1) {
        throw render::UsageError("the job has " + std::to_string(frame_count) +
                                 " frames: give --out DIR (without .exr) for all of them, or "
                                 "--frame F --out FILE.exr for one");
    } else {
        plan.frames = {0};
    }
    return plan;
}

int fetch_output(const Connection& c, const std::string& job_id, uint32_t frame_count,
                 std::optional<uint32_t> frame, bool preview, const std::string& out) {
    OutputPlan plan = output_plan(out, frame_count, frame);
    if (!plan.folder) return fetch(c, job_id, plan.frames[0], preview, out);
    fs::create_directories(out);
    int failed = 0;
    for (uint32_t f : plan.frames) {
        try {
            fetch(c, job_id, f, preview, (fs::path(out) / frame_file_name(f)).string());
        } catch (const RpcFailure& e) {
            std::fprintf(stderr, "client: frame %u: %s\n", f, e.what());
            ++failed;
        }
    }
    if (failed)
        std::fprintf(stderr, "client: %d of %zu frame(s) not fetched\n", failed,
                     plan.frames.size());
    return failed ? 1 : 0;
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
    if (!o.out.empty())
        output_plan(o.out, uint32_t(std::max<size_t>(1, frames.size())), std::nullopt);
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

// ---------------------------------------------------------------------------------------------
// watch, fetch, cancel, list, status

v1::Job get_job(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::GetJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    grpc::Status status = c.stub->GetJob(&context, request, &job);
    if (!status.ok()) throw RpcFailure("GetJob", status);
    return job;
}

int watch(const Connection& c, const std::string& job_id) {
    ProgressDisplay display(isatty(STDERR_FILENO));
    v1::Job last;
    bool have = false;
    int unavailable = 0;
    for (;;) {
        grpc::ClientContext context;
        c.prepare(context, 0);  // a watch lasts as long as the job
        v1::WatchJobRequest request;
        request.set_job_id(job_id);
        std::unique_ptr<grpc::ClientReader<v1::JobEvent>> reader =
            c.stub->WatchJob(&context, request);
        v1::JobEvent event;
        while (reader->Read(&event)) {
            last = event.job();
            have = true;
            unavailable = 0;
            display.update(last);
            if (is_terminal(last.state())) break;
        }
        if (have && is_terminal(last.state())) {
            context.TryCancel();
            reader->Finish();
            break;
        }
        grpc::Status status = reader->Finish();
        if (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
            // The server has as many watchers as it serves: poll instead.
            last = get_job(c, job_id);
            have = true;
            display.update(last);
            if (is_terminal(last.state())) break;
            std::this_thread::sleep_for(std::chrono::seconds(1));
            continue;
        }
        if (!status.ok()) {
            // Ride out a short server restart; give up after ~30 s.
            if (status.error_code() == grpc::StatusCode::UNAVAILABLE && ++unavailable <= 12) {
                std::this_thread::sleep_for(std::chrono::milliseconds(250 * unavailable));
                continue;
            }
            throw RpcFailure("WatchJob", status);
        }
        // The stream ended without a final state: ask, and watch again if needed.
        last = get_job(c, job_id);
        have = true;
        display.update(last);
        if (is_terminal(last.state())) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    display.finish();
    uint64_t iterations = 0;
    double seconds = 0, error = 0;
    for (const auto& f : last.frames()) {
        iterations += f.iterations_done();
        seconds = std::max(seconds, f.render_seconds());
        error = std::max(error, f.relative_error());
    }
    std::fprintf(stderr, "job %s %s: %d frame(s), %llu iterations, %s, estimated error %.3g%s%s\n",
                 last.id().c_str(), state_name(last.state()), last.frames_size(),
                 (unsigned long long)iterations, render::format_seconds(seconds).c_str(), error,
                 last.error().empty() ? "" : ": ", last.error().c_str());
    return last.state() == v1::JOB_STATE_DONE ? 0 : 1;
}

int fetch(const Connection& c, const std::string& job_id, uint32_t frame, bool preview,
          const std::string& out) {
    fs::path target(out);
    if (target.has_parent_path()) fs::create_directories(target.parent_path());
    fs::path tmp = target;
    tmp += ".part";
    grpc::ClientContext context;
    c.prepare(context, 600.0);
    v1::FetchResultRequest request;
    request.set_job_id(job_id);
    request.set_frame(frame);
    request.set_preview(preview);
    std::unique_ptr<grpc::ClientReader<v1::ResultChunk>> reader =
        c.stub->FetchResult(&context, request);
    uint64_t written = 0, total = 0;
    {
        std::ofstream file(tmp, std::ios::binary | std::ios::trunc);
        if (!file) throw std::runtime_error("cannot write " + tmp.string());
        v1::ResultChunk chunk;
        while (reader->Read(&chunk)) {
            if (chunk.total_size() > 0) total = chunk.total_size();
            file.write(chunk.data().data(), std::streamsize(chunk.data().size()));
            written += chunk.data().size();
        }
        file.close();
        if (!file) throw std::runtime_error("error writing " + tmp.string());
    }
    grpc::Status status = reader->Finish();
    if (!status.ok()) {
        fs::remove(tmp);
        throw RpcFailure("FetchResult", status);
    }
    if (written == 0 || (total > 0 && written != total)) {
        fs::remove(tmp);
        throw std::runtime_error("FetchResult: incomplete result (" + std::to_string(written) +
                                 " of " + std::to_string(total) + " bytes)");
    }
    fs::rename(tmp, target);
    std::fprintf(stderr, "client: wrote %s (frame %u%s, %.1f KiB)\n", out.c_str(), frame,
                 preview ? ", preview" : "", written / 1024.0);
    return 0;
}

std::string format_time(int64_t unix_ms) {
    if (unix_ms <= 0) return "-";
    std::time_t t = std::time_t(unix_ms / 1000);
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
    return buf;
}

int list(const Connection& c) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::ListJobsReply reply;
    grpc::Status status = c.stub->ListJobs(&context, v1::ListJobsRequest(), &reply);
    if (!status.ok()) throw RpcFailure("ListJobs", status);
    std::printf("%-24s %-10s %4s %-5s %7s %14s  %-19s  %s\n", "ID", "STATE", "PRIO", "ALGO",
                "FRAMES", "ITERATIONS", "SUBMITTED", "NAME");
    for (const v1::Job& job : reply.jobs()) {
        uint64_t done = 0, target = 0;
        int frames_done = 0;
        for (const auto& f : job.frames()) {
            done += f.iterations_done();
            target += f.iterations_target();
            frames_done += f.done();
        }
        std::string frames = std::to_string(frames_done) + "/" + std::to_string(job.frames_size());
        std::string its = std::to_string(done) + "/" + (target ? std::to_string(target) : "-");
        std::printf("%-24s %-10s %4d %-5s %7s %14s  %-19s  %s\n", job.id().c_str(),
                    state_name(job.state()), job.priority(), job.settings().algorithm().c_str(),
                    frames.c_str(), its.c_str(), format_time(job.submitted_unix_ms()).c_str(),
                    job.name().c_str());
        if (!job.waiting().empty()) std::printf("%-24s %s\n", "", job.waiting().c_str());
    }
    return 0;
}

int status(const Connection& c) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::ClusterStatusReply reply;
    grpc::Status s = c.stub->ClusterStatus(&context, v1::ClusterStatusRequest(), &reply);
    if (!s.ok()) throw RpcFailure("ClusterStatus", s);
    std::printf("server %s: %u queued, %u running, %u waiting for memory job(s), %d worker(s)\n",
                c.address.c_str(), reply.queued_jobs(), reply.running_jobs(), reply.waiting_jobs(),
                reply.workers_size());
    if (reply.workers_size() > 0)
        std::printf("%-24s %-20s %7s %10s  %s\n", "WORKER", "HOST", "THREADS", "SEEN", "LEASE");
    int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
    for (const v1::WorkerStatus& w : reply.workers()) {
        std::string seen =
            w.last_seen_unix_ms() > 0
                ? render::format_seconds((now - w.last_seen_unix_ms()) / 1000.0) + " ago"
                : "-";
        std::printf("%-24s %-20s %7u %10s  %s\n", w.worker_id().c_str(), w.host().c_str(),
                    w.threads(), seen.c_str(),
                    w.lease_id().empty() ? "idle" : w.lease_id().c_str());
    }
    return 0;
}

int cancel(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::CancelJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    grpc::Status s = c.stub->CancelJob(&context, request, &job);
    if (!s.ok()) throw RpcFailure("CancelJob", s);
    std::printf("job %s: %s\n", job.id().c_str(), state_name(job.state()));
    return 0;
}

int delete_job(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::DeleteJobRequest request;
    request.set_job_id(job_id);
    v1::DeleteJobReply reply;
    grpc::Status s = c.stub->DeleteJob(&context, request, &reply);
    if (!s.ok()) throw RpcFailure("DeleteJob", s);
    std::printf("job %s deleted: %llu asset(s) no other job uses removed, %s freed\n",
                job_id.c_str(), (unsigned long long)reply.assets_removed(),
                render::format_bytes(reply.bytes_freed()).c_str());
    return 0;
}

int bundle_command(const std::vector<std::string>& args) {
    std::string scene;
    std::map<std::string, std::string> defines;
    render::ArgumentParser p;
    p.value({"-D"}, "name=value", "",
            [&](const std::string& v) { defines.insert(render::parse_define("-D", v)); });
    p.positional([&](const std::string& v) {
        if (!scene.empty()) throw render::UsageError("bundle: unexpected argument " + v);
        scene = v;
    });
    p.parse(args);
    if (scene.empty()) usage_error("bundle: no scene file given");
    SceneBundleInfo b = collect_bundle(scene, defines);
    std::printf("# root %s, scene %s, integrator %s, sample_count %s\n", b.root.c_str(),
                b.scene_path.c_str(), b.integrator.empty() ? "?" : b.integrator.c_str(),
                b.sample_count ? std::to_string(*b.sample_count).c_str() : "?");
    for (const BundleEntry& e : b.files)
        std::printf("%s %10llu %s\n", e.sha256.c_str(), (unsigned long long)e.size, e.path.c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    render::service::prepare_grpc_process();
    std::string server, token, tls_ca, tls_server_name;
    if (const char* env = std::getenv("RENDER_SERVER"); env && *env) server = env;
    std::vector<std::string> rest;
    // Global options come before the command; everything from the command on is its own.
    int first = 1;
    for (; first < argc && argv[first][0] == '-'; ++first) {
        const std::string a = argv[first];
        if (a == "--help" || a == "-h") {
            std::cout << usage();
            return 0;
        }
        std::string* value = a == "--server"            ? &server
                             : a == "--token"           ? &token
                             : a == "--tls-ca"          ? &tls_ca
                             : a == "--tls-server-name" ? &tls_server_name
                                                        : nullptr;
        if (!value) usage_error("unknown option " + a);
        if (first + 1 >= argc) usage_error(a + " needs a value");
        *value = argv[++first];
    }
    rest.assign(argv + first, argv + argc);
    if (rest.empty()) usage_error("no command given");
    if (server.empty()) server = "127.0.0.1:50051";
    std::string command = rest[0];
    std::vector<std::string> args(rest.begin() + 1, rest.end());
    try {
        if (command == "hash") {
            if (args.empty()) usage_error("hash: no file given");
            for (const std::string& f : args)
                std::printf("%s  %s\n", render::sha256_file(f).c_str(), f.c_str());
            return 0;
        }
        if (command == "bundle") return bundle_command(args);

        Connection c;
        c.address = server;
        c.token = token_or_env(token);
        ClientTls tls;
        try {
            tls = client_tls_from(tls_ca, tls_server_name);
        } catch (const std::runtime_error& e) {
            std::fprintf(stderr, "client: %s\n", e.what());
            return 2;
        }
        if (const std::string problem = check_client_transport(server, tls.tls, !c.token.empty());
            !problem.empty()) {
            std::fprintf(stderr, "client: %s\n", problem.c_str());
            return 2;
        }
        c.stub = v1::JobService::NewStub(make_channel(server, tls));
        auto job_arg = [&](const char* cmd) -> std::string {
            if (args.empty() || args[0].empty() || args[0][0] == '-')
                usage_error(std::string(cmd) + ": no job id given");
            return args[0];
        };
        if (command == "submit") return submit(c, args);
        if (command == "watch") {
            if (args.size() != 1) usage_error("watch expects one job id");
            return watch(c, job_arg("watch"));
        }
        if (command == "fetch") {
            std::string job = job_arg("fetch"), out;
            std::optional<uint32_t> frame;
            bool preview = false;
            render::ArgumentParser p;
            p.value({"--frame"}, "F", "", [&](const std::string& v) {
                frame = render::parse_number<uint32_t>("--frame", v);
            });
            p.flag({"--preview"}, "", [&] { preview = true; });
            p.value({"--out", "-o"}, "FILE.exr|DIR", "", [&](const std::string& v) { out = v; });
            p.parse(std::vector<std::string>(args.begin() + 1, args.end()));
            if (out.empty()) usage_error("fetch: --out FILE.exr or --out DIR is required");
            const uint32_t frame_count = uint32_t(get_job(c, job).frames_size());
            return fetch_output(c, job, frame_count, frame, preview, out);
        }
        if (command == "cancel") {
            if (args.size() != 1) usage_error("cancel expects one job id");
            return cancel(c, job_arg("cancel"));
        }
        if (command == "delete") {
            if (args.size() != 1) usage_error("delete expects one job id");
            return delete_job(c, job_arg("delete"));
        }
        if (command == "list") return list(c);
        if (command == "status") return status(c);
        usage_error("unknown command " + command);
    } catch (const render::UsageError& e) {
        usage_error(e.what());
    } catch (const RpcFailure& e) {
        std::fprintf(stderr, "client: %s (server %s)%s\n", e.what(), server.c_str(),
                     connection_hint(e.status, tls_used(tls_ca)).c_str());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "client: error: %s\n", e.what());
        return 1;
    }
}
