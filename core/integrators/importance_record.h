#pragma once

// The four per-record VPL distributions of importance caching (Georgiev, Krivanek, Popov,
// Slusallek, EG 2012; thesis ch. 5; docs/design/algorithms-next.md section 2.2), as plain
// numbers: the integrator computes, for one importance record r and each of the iteration's M
// VPLs v, the luminances it needs, and this file turns them into tables.
//   F (full)          ~ lum h(r, v), visibility included
//   U (unoccluded)    ~ lum h(r, v) with V = 1
//   B (bounded)       ~ lum of a bound of the unoccluded contribution over the record's ball
//                       of radius rho (bounded_geometry_factor below)
//   C (conservative)  uniform over the VPLs that can contribute
// C is what makes the estimator unbiased: every VPL with h(x, v) > 0 at ANY shading point x
// that may use this record must be in C's mask, so the mask must not depend on the record
// (use "the VPL carries non-zero power", the same mask at every record and in the fallback).

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/integrators/importance_table.h"

namespace render {

// The techniques in the order the alpha-max heuristic ranks them (section 2.4).
enum class IcType : int { F = 0, U = 1, B = 2, C = 3 };
inline constexpr int kIcTypeCount = 4;
inline constexpr std::array<IcType, kIcTypeCount> kIcTypes = {IcType::F, IcType::U, IcType::B,
                                                              IcType::C};
inline constexpr const char* ic_type_name(IcType t) {
    constexpr const char* names[] = {"F", "U", "B", "C"};
    return names[int(t)];
}

// A value per technique, indexed by IcType.
template <class T>
struct PerIcType {
    std::array<T, kIcTypeCount> value{};
    T& operator[](IcType t) { return value[size_t(t)]; }
    const T& operator[](IcType t) const { return value[size_t(t)]; }
    bool operator==(const PerIcType&) const = default;
};

// The four tables of one record, each over the same M VPLs.
struct IcRecordTables {
    PerIcType<ImportanceTable> table;
    const ImportanceTable& operator[](IcType t) const { return table[t]; }
};

// F, U and B from their weights (luminances, one per VPL); C uniform over the VPLs with
// can_contribute[v] != 0 (the record-independent mask, see above). All four spans have size M.
IcRecordTables make_record_tables(std::span<const double> full, std::span<const double> unoccluded,
                                  std::span<const double> bounded,
                                  std::span<const uint8_t> can_contribute);

// The conservative table alone: uniform over the VPLs with can_contribute[v]. It is also the
// fallback of a shading point that has no usable record (importance_lookup.h).
ImportanceTable conservative_table(std::span<const uint8_t> can_contribute);

// The bounded geometry factor G_B of table B (section 2.2): an upper estimate of
// cos(theta_v) cos(theta_x) / |x - v|^2 over the shading points x of the record's ball of radius
// rho around r, with
//     d       = |r - v|,  d_min = d - rho,
//     theta_v^min = max(0, theta_v - asin(min(1, rho / d)))    (angle at the VPL)
//     theta_r^min = max(0, theta_r - 30 deg)                    (angle at the record)
//     G_B     = cos theta_v^min cos theta_r^min / d_min^2,
// cos_vpl = cos theta_v (VPL normal against the direction to r), cos_record = cos theta_r
// (record normal against the direction to v). Cosines are clamped to [-1, 1]; a bound cosine
// that is still <= 0 gives 0 (the VPL cannot light the ball from its back side).
//
// d <= rho (the VPL is inside the ball, including d = 0, a VPL exactly at the record): the
// true bound is infinite (1/d_min^2 with d_min = 0). We return 0, as pg2015 does, because
//   * no finite number is a bound there, and an infinite entry would turn B into a delta on
//     those VPLs and waste every B sample of the record on them;
//   * F and U of the same record see these VPLs with their real (large) contribution, and C
//     covers them, so the estimator stays unbiased (B only shapes the variance);
//   * the alternative of section 2.2, capping at the largest F/U entry of the table, needs the
//     whole table; a caller that prefers it can replace the zeros of VPLs with d <= rho.
// Non-finite inputs or rho < 0 also give 0. The result is always finite and >= 0.
double bounded_geometry_factor(double d, double rho, double cos_vpl, double cos_record);

// The same bound for a virtual *infinite* light (a VPL standing for a direction, no distance):
// cos theta_r^min only.
double bounded_geometry_factor_directional(double cos_record);

// The record-side angular allowance of G_B: 30 degrees (thesis, section 2.2).
inline constexpr double kIcRecordAngleAllowance = 0.52359877559829887;  // pi / 6

}  // namespace render
