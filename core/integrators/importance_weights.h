#pragma once

// MIS between the four importance-caching techniques F, U, B, C at one shading point
// (section 2.4), as pure functions of the per-technique mixture pmfs P_t(v | x) of one VPL v
// and the sample counts n_t, and the estimator's exact expectation (for tests).
//
// The estimator (section 2.1): for each technique t, n_t VPLs v_tk are drawn from P_t(. | x),
//     I^(x) = sum_t (1 / n_t) sum_k w_t(v_tk) h(x, v_tk) / P_t(v_tk | x).
// It is unbiased for I(x) = sum_v h(x, v) iff, for every v with h(x, v) > 0,
//     sum_t w_t(v) = 1   and   w_t(v) = 0 wherever n_t P_t(v | x) = 0,
// (section 0.3); every heuristic below guarantees both whenever some n_t P_t(v) > 0, which C
// ensures. n_t = 0 disables t (a subset of {F, U, B, C}; keep C).

#include <cstddef>
#include <functional>
#include <span>

#include "core/integrators/importance_record.h"

namespace render {

using IcSampleCounts = PerIcType<int>;

enum class IcHeuristic { AlphaMax, Balance, Power };

struct IcWeighting {
    IcHeuristic heuristic = IcHeuristic::AlphaMax;
    // Confidences of alpha-max, thesis defaults; alpha_F is never used (nothing ranks above F).
    PerIcType<double> alpha = {{1.0, 0.5, 0.5, 0.3}};
    double beta = 2;  // exponent of the power heuristic
};

// Alpha-max, the thesis's ordered version: with the enabled techniques in the order F, U, B, C,
// w_s = 1 for the first s with n_s P_s > 0 and P_s >= max over enabled i after s of alpha_i P_i,
// and 0 for all others. Exactly one technique gets 1 whenever some enabled P > 0: the last
// enabled technique with P > 0 always qualifies (nothing positive comes after it). All 0 when
// no enabled P is positive. (pg2015 compares with the max over all i of alpha_i P_i instead;
// both are partitions of unity.) The counts only enable: alpha-max compares P_t, not n_t P_t.
PerIcType<double> ic_alpha_max_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                       const PerIcType<double>& alpha);
// Balance heuristic: w_t = n_t P_t / sum_i n_i P_i.
PerIcType<double> ic_balance_weights(const PerIcType<double>& pmf, const IcSampleCounts& n);
// Power heuristic: w_t = (n_t P_t)^beta / sum_i (n_i P_i)^beta, computed on ratios to the
// largest n_i P_i so that tiny pmfs (M = 1e5) neither underflow to 0/0 nor lose the sum.
PerIcType<double> ic_power_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                   double beta);
// The heuristic chosen by `weighting`.
PerIcType<double> ic_mis_weights(const PerIcType<double>& pmf, const IcSampleCounts& n,
                                 const IcWeighting& weighting);

// What the integrator multiplies h(x, v) by for one sample v drawn from technique t:
// w_t(v) / (n_t P_t(v | x)), and 0 when that weight is 0 (never 0/0).
double ic_sample_factor(IcType t, const PerIcType<double>& pmf, const IcSampleCounts& n,
                        const IcWeighting& weighting);

// The exact expectation of I^(x), by enumerating every VPL:
//     E[I^(x)] = sum_t sum_v n_t s_t(v) * w_t(v) h(v) / (n_t P_t(v)),
// where s_t(v) (`sampled`) is the probability that one draw of t returns v, i.e. what the
// sampler really does, and P_t (`claimed`) the pmfs the estimator divides by and feeds into
// `weights`. With s = P and a partition of unity this is sum_v h(v); a test computes s
// independently of the code under test and plants errors in P or in the weights. A term with
// w_t h != 0 but P_t = 0 while s_t > 0 (a draw the estimator cannot weigh) makes the result
// +infinity. All spans have one entry per VPL.
using IcWeightFunction =
    std::function<PerIcType<double>(const PerIcType<double>& pmf, const IcSampleCounts& n)>;
double ic_expected_estimate(std::span<const double> h, std::span<const PerIcType<double>> sampled,
                            std::span<const PerIcType<double>> claimed, const IcSampleCounts& n,
                            const IcWeightFunction& weights);

}  // namespace render
