#pragma once

// One discrete distribution over the M VPLs of an iteration, as importance caching builds four
// of per record (Georgiev et al. EG 2012; docs/reference/algorithms.md, "Importance caching
// (core)").
//
// Why not Distribution1D: IC needs (i) cumulative sums and probabilities in double, since with
// M >= 1e5 VPLs a float CDF (spacing 6e-8 near 1) merges or drops the entries that are far
// below the mean 1/M, and those must keep a pmf that is exactly the probability with which
// they are drawn; (ii) a 53-bit uniform number to reach them; (iii) an *empty* state: a table
// whose weights are all zero is never sampled and has pmf 0 everywhere (Distribution1D samples
// uniformly then, which would silently give a pmf that the weights do not know about).
//
// The one invariant the estimator relies on: pmf(v) is the probability that sample() returns v
// for u uniform on [0, 1), computed from the same stored sums. pmf(v) is the width of v's
// interval of the cumulative sums divided by their total; that can differ from weight/total
// by rounding (relative error up to about 2^-53 / pmf: 1e-9 for an entry 1e-2 of the mean at
// M = 1e5, pmf 1e-7; 1e-5 for pmf 1e-11), and an entry that rounds to an empty interval has pmf 0
// and is never drawn. Both are harmless: the estimator only needs sampler and pmf to agree, and the
// conservative table C (integer sums, exact) covers every VPL regardless.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/sampling/rng.h"

namespace render {

class ImportanceTable {
  public:
    ImportanceTable() = default;  // empty, over zero VPLs
    // Weights per VPL; non-finite or negative weights count as 0. All zero: the table is empty.
    explicit ImportanceTable(std::span<const double> weights);

    size_t size() const { return cumulative_.empty() ? 0 : cumulative_.size() - 1; }
    bool empty() const { return !(total() > 0); }
    double total() const { return cumulative_.empty() ? 0.0 : cumulative_.back(); }

    // Probability that sample() returns v (0 for v out of range and for every v of an empty
    // table).
    double pmf(size_t v) const;

    // The VPL whose interval of the cumulative sums holds u * total(); never one of pmf 0.
    // Precondition: !empty(), u in [0, 1).
    size_t sample(double u) const;

  private:
    std::vector<double> cumulative_;  // size M + 1, cumulative_[0] = 0, not normalised
    size_t last_nonzero_ = 0;         // for u * total() rounding up to total()
};

// A uniform number in [0, 1) with 53 random bits (two 32-bit draws), so that entries of a
// table far below 2^-24 (the resolution of Rng::next_1d) can be drawn.
inline double next_double(Rng& rng) {
    const uint64_t hi = rng.next_u32() >> 6;  // 26 bits
    const uint64_t lo = rng.next_u32() >> 5;  // 27 bits
    return double((hi << 27) | lo) * 0x1p-53;
}

}  // namespace render
