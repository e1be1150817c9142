#include "core/integrators/importance_optimise.h"

#include <algorithm>
#include <vector>

namespace render {

IcRecordTables optimise_record_tables(const IcRecordTables& tables, const IcSampleCounts& n,
                                      const PerIcType<double>& alpha) {
    if (n[IcType::C] <= 0) return tables;
    size_t m = 0;
    for (IcType t : kIcTypes) m = std::max(m, tables[t].size());

    // Winner per VPL from the record's own pmfs; -1 when no enabled table holds it.
    std::vector<int> winner(m, -1);
    PerIcType<std::vector<double>> weights;
    for (IcType t : kIcTypes) weights[t].assign(m, 0.0);
    for (size_t v = 0; v < m; ++v) {
        PerIcType<double> own;
        for (IcType t : kIcTypes) own[t] = tables[t].pmf(v);
        const PerIcType<double> w = ic_alpha_max_weights(own, n, alpha);
        for (IcType t : kIcTypes)
            if (w[t] > 0) {
                winner[v] = int(t);
                // C stays uniform over what it keeps (weight 1, as conservative_table).
                weights[t][v] = t == IcType::C ? 1.0 : own[t];
            }
    }
    IcRecordTables out;
    for (IcType t : {IcType::F, IcType::U, IcType::B}) out.table[t] = ImportanceTable(weights[t]);
    // Entries rounded away by the renormalisation go to C, so no VPL loses every technique.
    for (size_t v = 0; v < m; ++v)
        if (winner[v] >= 0 && IcType(winner[v]) != IcType::C &&
            !(out[IcType(winner[v])].pmf(v) > 0))
            weights[IcType::C][v] = 1.0;
    out.table[IcType::C] = ImportanceTable(weights[IcType::C]);
    return out;
}

}  // namespace render
