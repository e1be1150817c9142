#include "core/integrators/importance_mixture.h"

#include <algorithm>
#include <stdexcept>

namespace render {

IcMixture::IcMixture(std::span<const IcRecordTables* const> records,
                     const ImportanceTable& fallback)
    : fallback_(&fallback) {
    record_count_ = int(std::min<size_t>(records.size(), kIcMaxRecords));
    std::copy_n(records.begin(), record_count_, records_.begin());
    for (IcType t : kIcTypes) {
        if (record_count_ == 0) {
            // The fallback: C alone (kept at index -1, see table()).
            usable_count_[t] = (t == IcType::C && !fallback.empty()) ? 1 : 0;
            continue;
        }
        for (int j = 0; j < record_count_; ++j)
            if (!(*records_[j])[t].empty()) usable_[t][usable_count_[t]++] = j;
    }
}

const ImportanceTable& IcMixture::table(IcType t, int k) const {
    if (record_count_ == 0) return *fallback_;
    return (*records_[usable_[t][k]])[t];
}

double IcMixture::pmf(IcType t, size_t v) const {
    const int n = usable_count_[t];
    if (n == 0) return 0.0;
    double sum = 0;
    for (int k = 0; k < n; ++k) sum += table(t, k).pmf(v);
    return sum / double(n);
}

PerIcType<double> IcMixture::pmfs(size_t v) const {
    PerIcType<double> p;
    for (IcType t : kIcTypes) p[t] = pmf(t, v);
    return p;
}

size_t IcMixture::sample(IcType t, double u_record, double u_vpl) const {
    const int n = usable_count_[t];
    if (n <= 0) throw std::logic_error("importance caching: a record type with no usable record");
    const int k = std::clamp(int(u_record * double(n)), 0, n - 1);
    return table(t, k).sample(u_vpl);
}

}  // namespace render
