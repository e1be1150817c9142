#pragma once

// The progress display of `client watch`: on a terminal one bar per frame, redrawn in place,
// with iterations/s, ETA and the estimated relative error; otherwise plain lines at every 10%
// of a frame, on state changes, and at least every 10 s.

#include <chrono>
#include <map>
#include <string>

#include "core/util/format_seconds.h"
#include "render.pb.h"

namespace render::service {
const char* state_name(v1::JobState state);
bool is_terminal(v1::JobState state);

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
};

}  // namespace render::service
