#pragma once

// Animations for `client submit`: the frames of one job and each frame's define overrides,
// from `--frames A:B` (with `{frame}` / `{frame:04}` in -D values) or `--frames-file F`. Pure
// functions (no RPC), unit-tested in tests/unit/client/client_frames_test.cpp.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace render::service {

using Defines = std::map<std::string, std::string>;

// The most frames one job may have (the server refuses more: server/validation.h).
inline constexpr int64_t kMaxJobFrames = 1000;

// "A:B": the frame numbers A, A+1, ..., B, both ends included (0:24 is 25 frames), with
// 0 <= A <= B <= 999999 and at most kMaxJobFrames frames. Throws UsageError naming --frames.
struct FrameRange {
    int64_t first = 0;
    int64_t last = 0;
    int64_t count() const { return last - first + 1; }
};
FrameRange parse_frame_range(const std::string& text);

// Whether `text` contains a `{frame...}` placeholder.
bool has_frame_placeholder(const std::string& text);

// `text` with every `{frame}` replaced by the frame number and every `{frame:0N}` by the
// number zero-padded to N digits (1 <= N <= 9; `{frame:N}` pads with zeros too). Any other
// `{frame...}` throws UsageError; other braces are kept as they are.
std::string substitute_frame(const std::string& text, int64_t frame);

// The per-frame overrides of `--frames A:B`: for each frame of the range, the defines whose
// value has a placeholder, substituted. (Defines without one are the job's, not the frames'.)
std::vector<Defines> range_frames(const FrameRange& range, const Defines& defines);

// A frames file: one line per frame of `name=value` pairs separated by spaces or tabs; blank
// lines and lines whose first non-blank character is `#` are skipped (a frame without
// overrides is a line with just `-`). Throws UsageError "FILE:LINE: ..." for a malformed
// pair, a name given twice on one line, or more than kMaxJobFrames frames; "FILE: ..." for an
// unreadable or frameless file. `name` is how errors name the file.
std::vector<Defines> parse_frames_text(const std::string& text, const std::string& name);
std::vector<Defines> read_frames_file(const std::filesystem::path& path);

// "name=value name2=value2" of a frame's overrides, for messages.
std::string format_defines(const Defines& defines);

// The file name of frame `index` in a `fetch --out DIR` folder: frame_0000.exr.
std::string frame_file_name(uint32_t index);

}  // namespace render::service
