#include "client/progress.h"

#include <algorithm>
#include <cstdio>

namespace render::service {

namespace {
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
constexpr size_t kMaxBars = 16;  // more frames: the first ones, then a summary line

double frame_fraction(const v1::Job& job, const v1::FrameStatus& f) {
    if (f.done()) return 1.0;
    double fraction = 0;
    if (f.iterations_target() > 0)
        fraction = double(f.iterations_done()) / double(f.iterations_target());
    double budget = job.settings().time_budget_seconds();
    if (budget > 0) fraction = std::max(fraction, f.render_seconds() / budget);
    return std::clamp(fraction, 0.0, 1.0);
}
}  // namespace

const char* state_name(v1::JobState state) {
    switch (state) {
        case v1::JOB_STATE_QUEUED:
            return "QUEUED";
        case v1::JOB_STATE_RUNNING:
            return "RUNNING";
        case v1::JOB_STATE_DONE:
            return "DONE";
        case v1::JOB_STATE_CANCELLED:
            return "CANCELLED";
        case v1::JOB_STATE_FAILED:
            return "FAILED";
        default:
            return "UNSPECIFIED";
    }
}

bool is_terminal(v1::JobState state) {
    return state == v1::JOB_STATE_DONE || state == v1::JOB_STATE_CANCELLED ||
           state == v1::JOB_STATE_FAILED;
}

ProgressDisplay::ProgressDisplay(bool tty) : tty_(tty) {}

std::string ProgressDisplay::frame_line(const v1::Job& job, const v1::FrameStatus& f,
                                        bool bar) const {
    double fraction = frame_fraction(job, f);
    char target[32] = "";
    if (f.iterations_target() > 0)
        std::snprintf(target, sizeof target, "/%llu", (unsigned long long)f.iterations_target());
    double eta = f.eta_seconds();
    char line[256];
    std::string bar_text;
    if (bar) {
        const int width = 30;
        int filled = int(fraction * width);
        bar_text.reserve(width + 3);
        bar_text += '[';
        bar_text.append(size_t(filled), '#');
        bar_text.append(size_t(width - filled), '.');
        bar_text += "] ";
    }
    std::snprintf(line, sizeof line,
                  "frame %u %s%3d%%  %llu%s it  %.2f it/s  err %.3g  %s  ETA %s%s", f.index(),
                  bar_text.c_str(), int(fraction * 100), (unsigned long long)f.iterations_done(),
                  target, f.iterations_per_second(), f.relative_error(),
                  format_seconds(f.render_seconds()).c_str(),
                  f.done() ? "-" : format_seconds(eta).c_str(), f.done() ? "  done" : "");
    return line;
}

void ProgressDisplay::update(const v1::Job& job) {
    auto now = Clock::now();
    bool state_changed = job.state() != last_state_;
    last_state_ = job.state();
    if (tty_) {
        if (!state_changed && !is_terminal(job.state()) && now - last_draw_ < 0.1s) return;
        last_draw_ = now;
        std::string out;
        if (drawn_lines_ > 0) out += "\x1b[" + std::to_string(drawn_lines_) + "F";
        int lines = 0;
        out += "\x1b[2Kjob " + job.id() + (job.name().empty() ? "" : " (" + job.name() + ")") +
               ": " + state_name(job.state()) + "\n";
        ++lines;
        size_t shown = std::min<size_t>(job.frames_size(), kMaxBars);
        for (size_t i = 0; i < shown; ++i, ++lines)
            out += "\x1b[2K" + frame_line(job, job.frames(int(i)), true) + "\n";
        if (size_t(job.frames_size()) > shown) {
            size_t done = 0;
            for (const auto& f : job.frames()) done += f.done();
            out += "\x1b[2K... " + std::to_string(job.frames_size()) + " frames, " +
                   std::to_string(done) + " done\n";
            ++lines;
        }
        std::fputs(out.c_str(), stderr);
        std::fflush(stderr);
        drawn_lines_ = lines;
        return;
    }
    bool print = state_changed || now - last_plain_ >= 10s;
    for (const auto& f : job.frames()) {
        int decile = int(frame_fraction(job, f) * 10);
        auto it = last_decile_.find(f.index());
        if (it == last_decile_.end() || it->second != decile) {
            last_decile_[f.index()] = decile;
            print = true;
        }
    }
    if (!print) return;
    last_plain_ = now;
    if (state_changed)
        std::fprintf(stderr, "job %s: %s\n", job.id().c_str(), state_name(job.state()));
    for (const auto& f : job.frames())
        std::fprintf(stderr, "  %s\n", frame_line(job, f, false).c_str());
    std::fflush(stderr);
}

void ProgressDisplay::finish() {}

}  // namespace render::service
