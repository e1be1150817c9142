#pragma once

// The importance-caching distribution of one shading point x: for each technique t in
// {F, U, B, C} the mixture of the tables of x's R nearest records (section 2.1),
//     P_t(v | x) = (1 / R_t) * sum over the records j whose t-table is not empty of P_t(v | r_j),
// sampled by picking one of those R_t records uniformly and drawing from its table.
//
// Empty tables. A record's table is empty when all its weights are zero (e.g. F of a record
// that sees no VPL). We leave such records out of that technique's mixture (R_t <= R) instead
// of picking them and drawing nothing: then every sample of t yields a VPL and the pmf above
// is exactly the probability of drawing v (picking with 1/R and wasting the draw would also be
// unbiased with 1/R, but throws samples away). The pmf used by the weights and the sampler
// are therefore one formula, on the same tables, with the same R_t. When R_t = 0 the technique
// is empty at x: it draws nothing, its pmf is 0 everywhere, and every MIS heuristic gives it
// weight 0 (importance_weights.h), so its n_t samples are simply not taken.
//
// No record at all (R = 0, nothing usable in range, importance_lookup.h): F, U and B are empty
// and C is the `fallback` table, uniform over every VPL that can contribute: the estimator
// degenerates to uniform VPL sampling, still unbiased.
//
// The mixture holds pointers to the record tables (no copies); they must outlive it.

#include <array>
#include <cstddef>
#include <span>

#include "core/integrators/importance_record.h"

namespace render {

// At most this many records per shading point (R = 3 by default, pg2015 uses 4).
inline constexpr int kIcMaxRecords = 8;

class IcMixture {
  public:
    // `records`: the tables of x's records (at most kIcMaxRecords are used, in the given
    // order); `fallback`: C over all VPLs, used only when `records` is empty.
    IcMixture(std::span<const IcRecordTables* const> records, const ImportanceTable& fallback);

    int record_count() const { return record_count_; }
    // Records whose t-table is not empty: R_t above.
    int usable_records(IcType t) const { return usable_count_[t]; }
    bool empty(IcType t) const { return usable_count_[t] == 0; }

    // P_t(v | x): exactly the probability that sample(t, ...) returns v.
    double pmf(IcType t, size_t v) const;
    PerIcType<double> pmfs(size_t v) const;

    // Picks a record with u_record (uniform among the R_t usable ones), then draws from its
    // table with u_vpl (use next_double: 53 bits). Precondition: !empty(t), u's in [0, 1).
    size_t sample(IcType t, double u_record, double u_vpl) const;

  private:
    const ImportanceTable& table(IcType t, int k) const;  // the k-th usable table of t

    std::array<const IcRecordTables*, kIcMaxRecords> records_{};
    int record_count_ = 0;
    const ImportanceTable* fallback_ = nullptr;
    PerIcType<std::array<int, kIcMaxRecords>> usable_{};  // indices into records_
    PerIcType<int> usable_count_{};
};

}  // namespace render
