#include "client/frames.h"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/util/arguments.h"

namespace render::service {

namespace {

constexpr int64_t kMaxFrameNumber = 999999;
const std::string kPlaceholder = "{frame";

bool all_digits(const std::string& s) {
    if (s.empty()) return false;
    for (char c : s)
        if (c < '0' || c > '9') return false;
    return true;
}

int64_t parse_frame_number(const std::string& text, const std::string& range) {
    if (!all_digits(text) || text.size() > 6)
        throw UsageError("--frames " + range + ": \"" + text + "\" is not a frame number in [0, " +
                         std::to_string(kMaxFrameNumber) + "] (expected A:B, e.g. 0:24)");
    return std::stoll(text);
}

}  // namespace

FrameRange parse_frame_range(const std::string& text) {
    size_t colon = text.find(':');
    if (colon == std::string::npos)
        throw UsageError("--frames " + text +
                         ": expected FIRST:LAST, both included (e.g. 0:24 for 25 frames)");
    FrameRange r;
    r.first = parse_frame_number(text.substr(0, colon), text);
    r.last = parse_frame_number(text.substr(colon + 1), text);
    if (r.last < r.first)
        throw UsageError("--frames " + text + ": the last frame " + std::to_string(r.last) +
                         " comes before the first " + std::to_string(r.first));
    if (r.count() > kMaxJobFrames)
        throw UsageError("--frames " + text + ": " + std::to_string(r.count()) +
                         " frames exceed the limit of " + std::to_string(kMaxJobFrames) +
                         " frames per job");
    return r;
}

bool has_frame_placeholder(const std::string& text) {
    return text.find(kPlaceholder) != std::string::npos;
}

std::string substitute_frame(const std::string& text, int64_t frame) {
    std::string out;
    size_t at = 0;
    for (size_t found; (found = text.find(kPlaceholder, at)) != std::string::npos;) {
        out.append(text, at, found - at);
        size_t close = text.find('}', found);
        if (close == std::string::npos)
            throw UsageError("\"" + text + "\": unterminated {frame placeholder");
        std::string spec =
            text.substr(found + kPlaceholder.size(), close - found - kPlaceholder.size());
        std::string number = std::to_string(frame);
        if (spec.empty()) {
            out += number;
        } else if (spec[0] == ':' && all_digits(spec.substr(1)) && spec.size() <= 3 &&
                   std::stoi(spec.substr(1)) >= 1 && std::stoi(spec.substr(1)) <= 9) {
            size_t width = size_t(std::stoi(spec.substr(1)));
            if (number.size() < width) number.insert(0, width - number.size(), '0');
            out += number;
        } else {
            throw UsageError("\"" + text + "\": \"" + text.substr(found, close - found + 1) +
                             "\" is not {frame} or {frame:0N} with 1 <= N <= 9");
        }
        at = close + 1;
    }
    out.append(text, at, std::string::npos);
    return out;
}

std::vector<Defines> range_frames(const FrameRange& range, const Defines& defines) {
    std::vector<Defines> frames;
    frames.reserve(size_t(range.count()));
    for (int64_t f = range.first; f <= range.last; ++f) {
        Defines d;
        for (const auto& [name, value] : defines)
            if (has_frame_placeholder(value)) d[name] = substitute_frame(value, f);
        frames.push_back(std::move(d));
    }
    return frames;
}

std::vector<Defines> parse_frames_text(const std::string& text, const std::string& name) {
    std::vector<Defines> frames;
    std::istringstream in(text);
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        const std::string where = name + ":" + std::to_string(number) + ": ";
        std::istringstream words(line);
        std::string word;
        Defines defines;
        bool any = false, dash = false;
        while (words >> word) {
            if (!any && word[0] == '#') break;
            any = true;
            if (word == "-") {
                dash = true;
                continue;
            }
            size_t eq = word.find('=');
            if (eq == std::string::npos || eq == 0)
                throw UsageError(where + "\"" + word +
                                 "\" is not name=value (a frame line is name=value pairs "
                                 "separated by spaces)");
            std::string key = word.substr(0, eq);
            if (!defines.emplace(key, word.substr(eq + 1)).second)
                throw UsageError(where + "\"" + key + "\" is given twice");
        }
        if (dash && !defines.empty())
            throw UsageError(where + "\"-\" (a frame without overrides) stands alone on its line");
        if (!any) continue;
        if (int64_t(frames.size()) >= kMaxJobFrames)
            throw UsageError(where + "more than " + std::to_string(kMaxJobFrames) +
                             " frames (the limit per job)");
        frames.push_back(std::move(defines));
    }
    if (frames.empty()) throw UsageError(name + ": no frames (every line is blank or a comment)");
    return frames;
}

std::vector<Defines> read_frames_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw UsageError("--frames-file " + path.string() + ": cannot read the file");
    std::ostringstream text;
    text << in.rdbuf();
    return parse_frames_text(text.str(), path.string());
}

std::string format_defines(const Defines& defines) {
    std::string out;
    for (const auto& [k, v] : defines) out += (out.empty() ? "" : " ") + k + "=" + v;
    return out.empty() ? "(no overrides)" : out;
}

std::string frame_file_name(uint32_t index) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04u.exr", index);
    return name;
}

}  // namespace render::service
