#pragma once

// Durations for progress lines: "12.3s", "4m05s", "2h07m". Negative or NaN reads as 0.

#include <cstdio>
#include <string>

namespace render {

inline std::string format_seconds(double s) {
    char buf[32];
    if (!(s >= 0)) s = 0;
    if (s < 60)
        std::snprintf(buf, sizeof buf, "%.1fs", s);
    else if (s < 3600)
        std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
    else
        std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, (int(s) % 3600) / 60);
    return buf;
}

}  // namespace render
