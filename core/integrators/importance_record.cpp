#include "core/integrators/importance_record.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace render {

ImportanceTable conservative_table(std::span<const uint8_t> can_contribute) {
    // Weights 1 and 0: the cumulative sums are integers, exact in double up to 2^53 VPLs, so
    // every VPL of the mask has exactly pmf 1 / count.
    std::vector<double> ones(can_contribute.size());
    for (size_t v = 0; v < ones.size(); ++v) ones[v] = can_contribute[v] ? 1.0 : 0.0;
    return ImportanceTable(ones);
}

IcRecordTables make_record_tables(std::span<const double> full, std::span<const double> unoccluded,
                                  std::span<const double> bounded,
                                  std::span<const uint8_t> can_contribute) {
    // A bug, never input: thrown, not asserted, so a worker fails the lease and lives
    // (docs/guide/reliability.md, "Resource limits").
    if (full.size() != can_contribute.size() || unoccluded.size() != can_contribute.size() ||
        bounded.size() != can_contribute.size())
        throw std::logic_error("importance records: the tables' sizes differ");
    IcRecordTables r;
    r.table[IcType::F] = ImportanceTable(full);
    r.table[IcType::U] = ImportanceTable(unoccluded);
    r.table[IcType::B] = ImportanceTable(bounded);
    r.table[IcType::C] = conservative_table(can_contribute);
    return r;
}

namespace {

// cos(max(0, theta - delta)) for theta = acos(c), delta >= 0; <= 0 maps to 0.
double bound_cosine(double c, double delta) {
    const double theta = std::acos(std::clamp(c, -1.0, 1.0));
    const double bound = std::cos(std::max(0.0, theta - delta));
    return bound > 0 ? bound : 0.0;
}

}  // namespace

double bounded_geometry_factor(double d, double rho, double cos_vpl, double cos_record) {
    if (!std::isfinite(d) || !std::isfinite(rho) || !std::isfinite(cos_vpl) ||
        !std::isfinite(cos_record) || rho < 0 || d < 0)
        return 0.0;
    if (d <= rho) return 0.0;  // inside the ball: unbounded, see the header
    const double d_min = d - rho;
    const double cos_v = bound_cosine(cos_vpl, std::asin(std::min(1.0, rho / d)));
    const double cos_r = bound_cosine(cos_record, kIcRecordAngleAllowance);
    const double g = cos_v * cos_r / (d_min * d_min);
    return std::isfinite(g) ? g : 0.0;  // d_min so small that the square underflows
}

double bounded_geometry_factor_directional(double cos_record) {
    if (!std::isfinite(cos_record)) return 0.0;
    return bound_cosine(cos_record, kIcRecordAngleAllowance);
}

}  // namespace render
