// `client fetch` (and `submit --out`): a frame's EXR, or every frame into a folder.

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "client/commands.h"
#include "client/frames.h"

namespace render::service {
namespace {

namespace fs = std::filesystem;

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

}  // namespace

void check_output(const std::string& out, uint32_t frame_count) {
    output_plan(out, frame_count, std::nullopt);
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

int fetch_command(const Connection& c, const Arguments& args) {
    std::string job = job_argument(args, "fetch"), out;
    std::optional<uint32_t> frame;
    bool preview = false;
    render::ArgumentParser p;
    p.value({"--frame"}, "F", "",
            [&](const std::string& v) { frame = render::parse_number<uint32_t>("--frame", v); });
    p.flag({"--preview"}, "", [&] { preview = true; });
    p.value({"--out", "-o"}, "FILE.exr|DIR", "", [&](const std::string& v) { out = v; });
    p.parse(std::vector<std::string>(args.begin() + 1, args.end()));
    if (out.empty()) usage_error("fetch: --out FILE.exr or --out DIR is required");
    const uint32_t frame_count = uint32_t(get_job(c, job).frames_size());
    return fetch_output(c, job, frame_count, frame, preview, out);
}

}  // namespace render::service
