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
bool started(const v1::FrameStatus& f) {
    return f.done() || f.iterations_done() > 0 || f.render_seconds() > 0;
}
}  // namespace

std::string frame_strip(const v1::Job& job, size_t width) {
    const size_t n = size_t(job.frames_size());
    size_t done = 0;
    for (const auto& f : job.frames()) done += f.done();
    std::string out = "frames " + std::to_string(done) + "/" + std::to_string(n) + " done [";
    width = std::max<size_t>(width, 1);
    const size_t per = (n + width - 1) / width;  // frames per character
    for (size_t start = 0; start < n; start += per) {
        // The least advanced frame of the group: not started < decile 0..9 < done.
        int rank = 11;
        for (size_t i = start; i < std::min(n, start + per); ++i) {
            const v1::FrameStatus& f = job.frames(int(i));
            int r = f.done()     ? 11
                    : started(f) ? 1 + std::min(9, int(frame_fraction(job, f) * 10))
                                 : 0;
            rank = std::min(rank, r);
        }
        out += rank == 11 ? '#' : rank == 0 ? '.' : char('0' + rank - 1);
    }
    out += ']';
    if (per > 1) out += " (" + std::to_string(per) + " frames per mark)";
    return out;
}

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
        case v1::JOB_STATE_WAITING:
            return "WAITING";
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
        if (job.frames_size() > 1) {
            out += "\x1b[2K" + frame_strip(job) + "\n";
            ++lines;
        }
        if (job.frames_size() <= kAllBarsFrames) {
            for (const auto& f : job.frames()) {
                out += "\x1b[2K" + frame_line(job, f, true) + "\n";
                ++lines;
            }
        } else {
            // An animation: bars for the frames being rendered only.
            size_t shown = 0, active = 0;
            for (const auto& f : job.frames()) {
                if (f.done() || !started(f)) continue;
                if (++active > kMaxBars) continue;
                out += "\x1b[2K" + frame_line(job, f, true) + "\n";
                ++lines;
                ++shown;
            }
            if (active > shown) {
                out += "\x1b[2K... and " + std::to_string(active - shown) + " more frames\n";
                ++lines;
            }
        }
        // Clear lines left over from a longer drawing.
        for (int extra = lines; extra < drawn_lines_; ++extra) out += "\x1b[2K\n";
        lines = std::max(lines, drawn_lines_);
        std::fputs(out.c_str(), stderr);
        std::fflush(stderr);
        drawn_lines_ = lines;
        return;
    }
    if (job.frames_size() > kAllBarsFrames) {
        // An animation: a line per finished frame, the strip on changes and every 10 s.
        if (state_changed)
            std::fprintf(stderr, "job %s: %s\n", job.id().c_str(), state_name(job.state()));
        for (const auto& f : job.frames())
            if (f.done() && !reported_done_[f.index()]) {
                reported_done_[f.index()] = true;
                std::fprintf(stderr, "  %s\n", frame_line(job, f, false).c_str());
            }
        std::string strip = frame_strip(job);
        if (strip != last_strip_ || now - last_plain_ >= 10s) {
            last_strip_ = strip;
            last_plain_ = now;
            std::fprintf(stderr, "  %s\n", strip.c_str());
        }
        std::fflush(stderr);
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
    if (job.frames_size() > 1) std::fprintf(stderr, "  %s\n", frame_strip(job).c_str());
    std::fflush(stderr);
}

void ProgressDisplay::finish() {}

}  // namespace render::service
