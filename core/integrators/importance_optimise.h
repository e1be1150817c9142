#pragma once

// The "distribution optimisation" of importance caching (thesis "FUBC alpha" vs "unopt";
// docs/design/algorithms-next.md section 2.4): at each record, a VPL keeps its entry only in the
// table of the technique that alpha-max gives it *at that record* (from the record's own
// pmfs), and every table is renormalised, so no sample drawn near the record is spent on a VPL
// another technique will be credited with.
//
// Why it stays unbiased. At every record, every VPL that had a positive pmf in some enabled
// table keeps a positive pmf in exactly one optimised table (its winner; alpha-max picks only
// techniques with P > 0). Rounding could still empty the winner's entry in the renormalised
// cumulative sums; such a VPL is put into C instead (C's sums are integers: exact). So each
// record's tables cover exactly the same VPLs as before. C's mask is record-independent and
// covers every VPL with h(x, v) > 0, hence at any shading point x some optimised mixture
// P_t(v | x) > 0 for every such v, and the weights at x -- recomputed by the caller from the
// *optimised* mixtures, which are exactly what is sampled -- are a partition of unity there.
// (Weights at x computed from the unoptimised pmfs would NOT do: they could credit a technique
// whose optimised tables no longer hold v.) Tested by importance_cache_test's exact expectation.
//
// Only for alpha-max (balance and power weights are never 0, nothing to remove). `n` must be
// the sample counts used at the shading points (the enabled set decides the winners); C must
// be enabled, otherwise the tables are returned unchanged.

#include "core/integrators/importance_record.h"
#include "core/integrators/importance_weights.h"

namespace render {

IcRecordTables optimise_record_tables(const IcRecordTables& tables, const IcSampleCounts& n,
                                      const PerIcType<double>& alpha);

}  // namespace render
