#pragma once

// The progress display of `client watch`: on a terminal one bar per frame, redrawn in place,
// with iterations/s, ETA and the estimated relative error; otherwise plain lines at every 10%
// of a frame, on state changes, and at least every 10 s. A job of more than
// kAllBarsFrames frames (an animation) shows a one-line strip of every frame instead (see
// frame_strip), bars only for the frames being rendered on a terminal, and otherwise a line
// per finished frame.

#include <chrono>
#include <map>
#include <string>

#include "core/util/format_seconds.h"
#include "render.pb.h"

namespace render::service {
const char* state_name(v1::JobState state);
bool is_terminal(v1::JobState state);

inline constexpr int kAllBarsFrames = 4;

// "frames 3/25 done [###7.3.........]": one character per frame, '#' done, '0'..'9' the tens
// of percent of a frame that has started, '.' a frame that has not; with more frames than
// `width`, a character stands for consecutive frames and shows the least advanced.
std::string frame_strip(const v1::Job& job, size_t width = 100);

class ProgressDisplay {
  public:
    explicit ProgressDisplay(bool tty);
    void update(const v1::Job& job);
    void finish();

  private:
    std::string frame_line(const v1::Job& job, const v1::FrameStatus& frame, bool bar) const;

    bool tty_;
    int drawn_lines_ = 0;
    std::chrono::steady_clock::time_point last_draw_{}, last_plain_{};
    v1::JobState last_state_ = v1::JOB_STATE_UNSPECIFIED;
    std::map<uint32_t, int> last_decile_;
    std::map<uint32_t, bool> reported_done_;
    std::string last_strip_;
};

}  // namespace render::service
