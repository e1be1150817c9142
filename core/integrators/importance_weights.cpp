#include "core/integrators/importance_weights.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace render {

namespace {

// n_t P_t, 0 for disabled or non-positive (and NaN) entries.
PerIcType<double> effective(const PerIcType<double>& pmf, const IcSampleCounts& n) {
    PerIcType<double> q;
    for (IcType t : kIcTypes) q[t] = n[t] > 0 && pmf[t] > 0 ? double(n[t]) * pmf[t] : 0.0;
    return q;
}

}  // namespace

PerIcType<double> ic_alpha_max_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                       const PerIcType<double>& alpha) {
    PerIcType<double> w;
    const PerIcType<double> q = effective(pmf, n);
    for (int s = 0; s < kIcTypeCount; ++s) {
        const IcType ts = IcType(s);
        if (!(q[ts] > 0)) continue;
        double best_after = 0;  // max over enabled i after s of alpha_i P_i
        for (int i = s + 1; i < kIcTypeCount; ++i)
            if (q[IcType(i)] > 0)
                best_after = std::max(best_after, alpha[IcType(i)] * pmf[IcType(i)]);
        if (pmf[ts] >= best_after) {
            w[ts] = 1;
            return w;
        }
    }
    return w;  // no enabled technique can draw v
}

PerIcType<double> ic_balance_weights(const PerIcType<double>& pmf, const IcSampleCounts& n) {
    return ic_power_weights(pmf, n, 1.0);
}

PerIcType<double> ic_power_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                   double beta) {
    PerIcType<double> w;
    const PerIcType<double> q = effective(pmf, n);
    const double largest = *std::max_element(q.value.begin(), q.value.end());
    if (!(largest > 0)) return w;
    double sum = 0;
    for (IcType t : kIcTypes) {
        // Ratio in (0, 1]; the largest technique contributes exactly 1, so sum >= 1.
        w[t] = q[t] > 0 ? (beta == 1 ? q[t] / largest : std::pow(q[t] / largest, beta)) : 0.0;
        sum += w[t];
    }
    for (IcType t : kIcTypes) w[t] /= sum;
    return w;
}

PerIcType<double> ic_mis_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                 const IcWeighting& weighting) {
    switch (weighting.heuristic) {
        case IcHeuristic::AlphaMax:
            return ic_alpha_max_weights(pmf, n, weighting.alpha);
        case IcHeuristic::Balance:
            return ic_balance_weights(pmf, n);
        case IcHeuristic::Power:
            return ic_power_weights(pmf, n, weighting.beta);
    }
    return {};
}

double ic_sample_factor(IcType t, const PerIcType<double>& pmf, const IcSampleCounts& n,
                        const IcWeighting& weighting) {
    const double w = ic_mis_weights(pmf, n, weighting)[t];
    if (!(w > 0)) return 0.0;
    return w / (double(n[t]) * pmf[t]);  // w > 0 implies n_t P_t > 0
}

double ic_expected_estimate(std::span<const double> h, std::span<const PerIcType<double>> sampled,
                            std::span<const PerIcType<double>> claimed, const IcSampleCounts& n,
                            const IcWeightFunction& weights) {
    double sum = 0;
    for (size_t v = 0; v < h.size(); ++v) {
        const PerIcType<double> w = weights(claimed[v], n);
        for (IcType t : kIcTypes) {
            if (n[t] <= 0 || !(sampled[v][t] > 0)) continue;  // t never draws v
            const double contribution = w[t] * h[v];
            if (contribution == 0) continue;
            if (!(claimed[v][t] > 0)) return std::numeric_limits<double>::infinity();
            // n_t draws, each v with probability s_t(v), each adding w h / (n_t P_t).
            sum += double(n[t]) * sampled[v][t] * contribution / (double(n[t]) * claimed[v][t]);
        }
    }
    return sum;
}

}  // namespace render
