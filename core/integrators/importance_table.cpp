#include "core/integrators/importance_table.h"

#include <algorithm>
#include <cmath>

namespace render {

ImportanceTable::ImportanceTable(std::span<const double> weights) {
    cumulative_.resize(weights.size() + 1);
    cumulative_[0] = 0;
    for (size_t v = 0; v < weights.size(); ++v) {
        const double w = std::isfinite(weights[v]) && weights[v] > 0 ? weights[v] : 0.0;
        cumulative_[v + 1] = cumulative_[v] + w;
        if (cumulative_[v + 1] > cumulative_[v]) last_nonzero_ = v;
    }
    // A sum that overflowed to infinity would make every pmf NaN: treat it as empty (the
    // caller's weights are luminances, so this means a broken input, and C still covers).
    if (!std::isfinite(total())) std::fill(cumulative_.begin(), cumulative_.end(), 0.0);
}

double ImportanceTable::pmf(size_t v) const {
    if (v >= size() || empty()) return 0.0;
    return (cumulative_[v + 1] - cumulative_[v]) / total();
}

size_t ImportanceTable::sample(double u) const {
    const double target = u * total();
    // First v with cumulative_[v + 1] > target: then cumulative_[v] <= target, so v's
    // interval is not empty and has width pmf(v) * total().
    const auto it = std::upper_bound(cumulative_.begin() + 1, cumulative_.end(), target);
    if (it == cumulative_.end()) return last_nonzero_;  // u * total() rounded up to total()
    return size_t(it - (cumulative_.begin() + 1));
}

}  // namespace render
