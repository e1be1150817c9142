#include "server/validation.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "core/base/memory_budget.h"
#include "core/render/algorithms.h"
#include "core/render/job_limits.h"
#include "core/util/sha256.h"
#include "service/request_options.h"

namespace render::server {

std::string check_bundle_path(const std::string& path) {
    if (path.empty()) return "is empty";
    if (path.size() > kMaxPathLength) return "is longer than 1024 characters";
    if (path.front() == '/') return "\"" + path + "\" is absolute";
    if (path.find('\\') != std::string::npos) return "\"" + path + "\" contains a backslash";
    for (char c : path)
        if (static_cast<unsigned char>(c) < 0x20)
            return "\"" + path + "\" contains a control character";
    size_t start = 0;
    while (true) {
        size_t slash = path.find('/', start);
        std::string part =
            path.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
        if (part == "..") return "\"" + path + "\" escapes the job folder (\"..\")";
        if (part.empty()) return "\"" + path + "\" has an empty part";
        if (part == ".") return "\"" + path + "\" has a \".\" part";
        if (slash == std::string::npos) break;
        start = slash + 1;
    }
    return {};
}

bool is_safe_id(const std::string& id) {
    if (id.empty() || id.size() > 64) return false;
    for (char c : id)
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '-' || c == '_'))
            return false;
    return true;
}

namespace {

using grpc::Status;
using grpc::StatusCode;

Status invalid(const std::string& message) {
    return Status(StatusCode::INVALID_ARGUMENT, message);
}

Status check_defines(const google::protobuf::Map<std::string, std::string>& defines,
                     const std::string& where) {
    if (defines.size() > 1000) return invalid(where + " has more than 1000 defines");
    for (const auto& [k, v] : defines) {
        if (k.empty()) return invalid(where + " has a define with an empty name");
        if (k.size() > 256 || v.size() > 65536)
            return invalid(where + " define \"" + k.substr(0, 64) + "\" is too long");
    }
    return Status::OK;
}

}  // namespace

Status check_submit_request(const v1::SubmitJobRequest& r, uint64_t max_job_assets) {
    const v1::RenderSettings& s = r.settings();
    // The server's limit, never above the protocol's.
    const uint64_t job_assets_limit = std::min(max_job_assets, kMaxBundleSize);
    const std::string job_assets_source =
        "server --max-job-assets " + format_bytes(job_assets_limit);
    if (r.name().size() > 1024) return invalid("name is longer than 1024 characters");
    if (!s.algorithm().empty() && !find_algorithm(s.algorithm()))
        return invalid("settings.algorithm \"" + s.algorithm().substr(0, 64) + "\" is not one of " +
                       algorithm_names());
    if (s.iterations() > kMaxIterations)
        return invalid("settings.iterations " + std::to_string(s.iterations()) +
                       " is out of range [1, " + std::to_string(kMaxIterations) + "]");
    if (!std::isfinite(s.time_budget_seconds()) || s.time_budget_seconds() < 0 ||
        s.time_budget_seconds() > kMaxTimeBudgetSeconds)
        return invalid("settings.time_budget_seconds must be a finite number in [0, " +
                       std::to_string(int64_t(kMaxTimeBudgetSeconds)) + "]");
    if (!std::isfinite(s.target_error()) || s.target_error() < 0 ||
        s.target_error() > kMaxTargetError)
        return invalid("settings.target_error must be a finite number in [0, " +
                       std::to_string(int(kMaxTargetError)) + "]");
    if (s.width() > uint32_t(kMaxFilmResolution) || s.height() > uint32_t(kMaxFilmResolution))
        return invalid("settings.width/height " + std::to_string(s.width()) + "x" +
                       std::to_string(s.height()) + " exceeds " +
                       std::to_string(kMaxFilmResolution));
    if ((s.width() == 0) != (s.height() == 0))
        return invalid("settings.width and settings.height must both be set or both be 0");
    // The legacy typed fields (0 = unset) and the options map, checked against the render
    // options table; whether the algorithm reads them is checked once the scene names it.
    if (!std::isfinite(s.radius_factor()) || !std::isfinite(s.alpha()))
        return invalid("settings.radius_factor and settings.alpha must be finite");
    try {
        if (std::string e = service::check_request_options(service::request_options(s)); !e.empty())
            return invalid(e);
    } catch (const std::invalid_argument& e) {
        return invalid(e.what());
    }
    if (Status st = check_defines(s.defines(), "settings"); !st.ok()) return st;
    if (size_t(r.frames_size()) > kMaxFrames)
        return invalid("frames: " + std::to_string(r.frames_size()) + " frames exceed 1000");
    if (std::string e =
            check_job_iterations(s.iterations(), uint64_t(std::max(1, r.frames_size())));
        !e.empty())
        return invalid(e);
    for (int i = 0; i < r.frames_size(); ++i)
        if (Status st = check_defines(r.frames(i).defines(), "frames[" + std::to_string(i) + "]");
            !st.ok())
            return st;
    const v1::SceneBundle& b = r.bundle();
    if (b.files_size() == 0) return invalid("bundle.files is empty");
    if (size_t(b.files_size()) > kMaxBundleFiles)
        return Status(StatusCode::RESOURCE_EXHAUSTED, "bundle has more than 10000 files");
    std::set<std::string> paths;
    uint64_t total = 0;
    for (const v1::BundleFile& f : b.files()) {
        if (std::string e = check_bundle_path(f.path()); !e.empty())
            return invalid("bundle path " + e);
        if (!is_sha256_hex(f.sha256()))
            return invalid("bundle file \"" + f.path() +
                           "\": sha256 must be 64 lower-case hex digits");
        if (!paths.insert(f.path()).second)
            return invalid("bundle path \"" + f.path() + "\" appears twice");
        if (f.size() > kMaxAssetSize)
            return Status(StatusCode::RESOURCE_EXHAUSTED,
                          "bundle file \"" + f.path() + "\" of " + std::to_string(f.size()) +
                              " bytes exceeds the asset size limit of 4 GiB");
        total += f.size();
        if (total > job_assets_limit)
            return Status(StatusCode::RESOURCE_EXHAUSTED,
                          "bundle.files total more than " + std::to_string(job_assets_limit) +
                              " bytes, the per-job size limit (" + job_assets_source + ")");
    }
    if (std::string e = check_bundle_path(b.scene_path()); !e.empty())
        return invalid("bundle.scene_path " + e);
    if (!paths.count(b.scene_path()))
        return invalid("bundle.scene_path \"" + b.scene_path() + "\" is not one of bundle.files");
    // A file and a folder of the same name cannot both exist.
    for (const std::string& p : paths)
        for (size_t slash = p.find('/'); slash != std::string::npos; slash = p.find('/', slash + 1))
            if (paths.count(p.substr(0, slash)))
                return invalid("bundle path \"" + p.substr(0, slash) +
                               "\" is both a file and a folder");
    return Status::OK;
}

}  // namespace render::server
