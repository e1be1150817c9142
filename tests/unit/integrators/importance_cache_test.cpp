// Importance caching, the pure core (core/integrators/importance_*.h): per-record tables, the
// bounded geometry factor, the mixture over a shading point's records, the MIS weights
// between F, U, B and C, the estimator's exact expectation and the record lookup. Everything
// here is exact or enumerated (no rendering); the mixture's sampler is checked against its pmf
// with the chi-square harness.
//
// The suites are named importance_cache_* so that `ctest -R importance_cache` selects them.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "core/integrators/importance_lookup.h"
#include "core/integrators/importance_mixture.h"
#include "core/integrators/importance_optimise.h"
#include "core/integrators/importance_record.h"
#include "core/integrators/importance_table.h"
#include "core/integrators/importance_weights.h"
#include "core/sampling/rng.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

double relative_error(double a, double b) {
    return std::abs(a - b) / std::max(std::abs(b), 1e-300);
}

// ---------------------------------------------------------------------------------------------
// Tables

TEST(importance_cache_table, PmfIsNormalisedWeightAndZerosAreNeverDrawn) {
    const std::vector<double> w = {1, 0, 3, 2, 0, 0.5, 0, -4, std::nan(""), INFINITY};
    const ImportanceTable t(w);
    ASSERT_EQ(t.size(), w.size());
    ASSERT_FALSE(t.empty());
    EXPECT_DOUBLE_EQ(t.total(), 6.5);  // negative, NaN and infinite weights count as 0
    const std::vector<double> expected = {1 / 6.5, 0, 3 / 6.5, 2 / 6.5, 0, 0.5 / 6.5, 0, 0, 0, 0};
    for (size_t v = 0; v < w.size(); ++v) EXPECT_DOUBLE_EQ(t.pmf(v), expected[v]) << v;
    EXPECT_EQ(t.pmf(w.size()), 0.0);
    // A sweep of u, including exactly the steps of the cumulative sums and just below 1.
    std::vector<double> us = {0.0, 1 / 6.5, 4 / 6.5, 6 / 6.5, std::nextafter(1.0, 0.0)};
    for (int i = 0; i < 10000; ++i) us.push_back(i / 10000.0);
    for (double u : us) {
        const size_t v = t.sample(u);
        ASSERT_LT(v, w.size());
        EXPECT_GT(t.pmf(v), 0.0) << "u = " << u;
    }
    EXPECT_EQ(t.sample(std::nextafter(1.0, 0.0)), 5u);  // the last non-zero entry
}

TEST(importance_cache_table, AllZeroIsEmpty) {
    const std::vector<double> zeros(5, 0.0);
    const ImportanceTable t(zeros);
    EXPECT_TRUE(t.empty());
    for (size_t v = 0; v < 5; ++v) EXPECT_EQ(t.pmf(v), 0.0);
    EXPECT_TRUE(ImportanceTable().empty());
    EXPECT_EQ(ImportanceTable().size(), 0u);
    // A total that overflows is treated as empty (never NaN pmfs).
    const std::vector<double> huge = {1e308, 1e308};
    EXPECT_TRUE(ImportanceTable(huge).empty());
}

// M = 1e5: an entry 1e-6 of the others' weight (pmf ~1e-11, far below float's CDF spacing of
// 6e-8 and below the 2^-24 resolution of a 24-bit u) keeps its pmf to 1e-4 relative and is
// drawn by the u inside its interval.
TEST(importance_cache_table, TinyEntryOfALargeTableKeepsItsPmf) {
    constexpr size_t kM = 100000, kTiny = 60000;
    std::vector<double> w(kM, 1.0);
    w[kTiny] = 1e-6;
    const ImportanceTable t(w);
    const double total = double(kM - 1) + 1e-6;
    EXPECT_LT(relative_error(t.pmf(kTiny), 1e-6 / total), 1e-4);
    EXPECT_LT(relative_error(t.pmf(kTiny - 1), 1 / total), 1e-9);
    EXPECT_LT(relative_error(t.pmf(kTiny + 1), 1 / total), 1e-9);
    // The weights before kTiny are 1, so its interval starts at exactly kTiny.
    EXPECT_EQ(t.sample((double(kTiny) + 0.5e-6) / total), kTiny);
    EXPECT_EQ(t.sample((double(kTiny) - 0.5) / total), kTiny - 1);
    EXPECT_EQ(t.sample((double(kTiny) + 0.5) / total), kTiny + 1);
    double sum = 0;
    for (size_t v = 0; v < kM; ++v) sum += t.pmf(v);
    EXPECT_NEAR(sum, 1.0, 1e-10);  // 1e5 terms summed naively here
    // The same entry in float would be gone: 1e-11 is below float's spacing near 0.6.
    EXPECT_EQ(float(0.6 + t.pmf(kTiny)) - 0.6f, 0.0f);
}

TEST(importance_cache_table, NextDoubleIsInUnitIntervalWith53Bits) {
    Rng rng(StreamKey{3, 0, 1, 0});
    bool below_2_24 = false;  // a value whose low bits are set: more than 24 bits
    for (int i = 0; i < 100000; ++i) {
        const double u = next_double(rng);
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        if (std::fmod(u * 0x1p24, 1.0) != 0) below_2_24 = true;
    }
    EXPECT_TRUE(below_2_24);
}

// ---------------------------------------------------------------------------------------------
// The bounded geometry factor

TEST(importance_cache_bounded_geometry, FollowsTheFormula) {
    const double deg = M_PI / 180;
    // d = 2, rho = 1: d_min = 1, theta_v 60 deg - asin(1/2) = 30 deg, theta_r 45 - 30 = 15 deg.
    EXPECT_NEAR(bounded_geometry_factor(2, 1, std::cos(60 * deg), std::cos(45 * deg)),
                std::cos(30 * deg) * std::cos(15 * deg), 1e-12);
    // rho = 0: only the record-side allowance remains; angles below it bound to cos 0 = 1.
    EXPECT_NEAR(bounded_geometry_factor(4, 0, 0.5, std::cos(20 * deg)), 0.5 / 16, 1e-12);
    // The bound is at least the point value cos_v cos_r / d^2 at the record itself.
    for (double d : {0.5, 1.0, 3.0})
        for (double c : {0.1, 0.5, 0.9})
            EXPECT_GE(bounded_geometry_factor(d, 0.2, c, c), c * c / (d * d));
    // A VPL facing away from the whole ball: 0; one facing away from the record but not from
    // the whole ball (theta_v = 100 deg, asin(rho / d) = 30 deg): positive.
    EXPECT_EQ(bounded_geometry_factor(2, 0.1, -0.9, 1), 0.0);
    EXPECT_GT(bounded_geometry_factor(2, 1, std::cos(100 * deg), 1), 0.0);
    EXPECT_NEAR(bounded_geometry_factor_directional(std::cos(50 * deg)), std::cos(20 * deg), 1e-12);
    EXPECT_EQ(bounded_geometry_factor_directional(std::cos(10 * deg)), 1.0);
}

// A VPL inside the record's ball (d <= rho), in particular exactly at the record (d = 0):
// the bound is infinite; we return 0 (finite, C and F/U cover the VPL), never NaN or inf.
TEST(importance_cache_bounded_geometry, InsideTheBallIsFiniteZero) {
    for (double rho : {0.0, 0.1, 1.0}) {
        EXPECT_EQ(bounded_geometry_factor(0, rho, 1, 1), 0.0) << rho;
        EXPECT_EQ(bounded_geometry_factor(rho, rho, 1, 1), 0.0) << rho;
        EXPECT_EQ(bounded_geometry_factor(rho / 2, rho, 0.3, 0.7), 0.0) << rho;
    }
    // Just outside: large but finite; a d_min whose square underflows: 0 as inside.
    const double just = bounded_geometry_factor(1 + 1e-6, 1, 1, 1);
    EXPECT_TRUE(std::isfinite(just) && just > 1e10) << just;
    EXPECT_EQ(bounded_geometry_factor(1e-200, 0, 1, 1), 0.0);
    for (double bad : {std::nan(""), double(INFINITY), -1.0})
        EXPECT_EQ(bounded_geometry_factor(bad, 0.1, 1, 1), 0.0);
    EXPECT_EQ(bounded_geometry_factor(1, std::nan(""), 1, 1), 0.0);
    EXPECT_EQ(bounded_geometry_factor(1, 0.1, std::nan(""), 1), 0.0);
    EXPECT_EQ(bounded_geometry_factor(1, -0.1, 1, 1), 0.0);
    // Cosines slightly outside [-1, 1] (rounding) are clamped, not NaN.
    EXPECT_TRUE(std::isfinite(bounded_geometry_factor(2, 0.5, 1 + 1e-7, 1 + 1e-7)));
}

// ---------------------------------------------------------------------------------------------
// Scenarios for the exact expectation: VPLs with contributions h, records with F/U/B weights.

struct Scenario {
    std::vector<double> h;                                    // h(x, v) at the shading point
    std::vector<uint8_t> mask;                                // C's mask (record-independent)
    std::vector<std::array<std::vector<double>, 3>> weights;  // per record: F, U, B weights
    std::vector<IcRecordTables> tables;
    ImportanceTable fallback;

    void build() {
        tables.clear();
        for (const auto& w : weights) tables.push_back(make_record_tables(w[0], w[1], w[2], mask));
        fallback = conservative_table(mask);
    }
    size_t m() const { return h.size(); }
};

double uniform(Rng& rng) {
    return next_double(rng);
}

// Random VPLs and records. Some h are 0; the VPL `only_c` has h > 0 but F = U = B = 0 at every
// record; with `all_f_zero` every record's F table is empty.
Scenario random_scenario(Rng& rng, size_t m, int record_count, bool all_f_zero) {
    Scenario s;
    s.h.resize(m);
    s.mask.resize(m);
    for (size_t v = 0; v < m; ++v) {
        s.h[v] = uniform(rng) < 0.25 ? 0.0 : std::exp(6 * uniform(rng) - 3);
        // Every VPL with h > 0 must be in C; some with h = 0 are too.
        s.mask[v] = s.h[v] > 0 || uniform(rng) < 0.5;
    }
    const size_t only_c = m > 1 ? m - 1 : m;  // the last VPL, when there are two or more
    if (only_c < m) {
        s.h[only_c] = 0.7;
        s.mask[only_c] = 1;
    }
    for (int j = 0; j < record_count; ++j) {
        std::array<std::vector<double>, 3> w;
        for (auto& table : w) table.assign(m, 0.0);
        for (size_t v = 0; v < m; ++v) {
            if (v == only_c || !s.mask[v]) continue;
            const double u = uniform(rng) < 0.3 ? 0.0 : uniform(rng);
            w[1][v] = u;                                                          // U
            w[0][v] = all_f_zero || uniform(rng) < 0.4 ? 0.0 : u * uniform(rng);  // F <= U
            w[2][v] = uniform(rng) < 0.2 ? 0.0 : u + uniform(rng);                // B >= U, mostly
        }
        // One record in three has an empty U table: exercises R_t < R.
        if (j % 3 == 1) std::fill(w[1].begin(), w[1].end(), 0.0);
        s.weights.push_back(w);
    }
    s.build();
    return s;
}

// The probability that one draw of technique t at x returns v, computed from the raw weights
// as the sampler is specified (a record picked uniformly among those whose t-weights are not
// all zero, then v in proportion to its weight), independently of ImportanceTable and
// IcMixture. C: uniform over the mask.
std::vector<PerIcType<double>> reference_sampling(const Scenario& s,
                                                  const std::vector<int>& records) {
    std::vector<PerIcType<double>> p(s.m());
    const double mask_count = std::accumulate(s.mask.begin(), s.mask.end(), 0.0);
    for (IcType t : kIcTypes) {
        std::vector<const std::vector<double>*> usable;
        std::vector<std::vector<double>> c_weights;
        if (t == IcType::C) {
            std::vector<double> c(s.m());
            for (size_t v = 0; v < s.m(); ++v) c[v] = s.mask[v] ? 1.0 : 0.0;
            c_weights.push_back(c);
            if (mask_count > 0) usable.push_back(&c_weights.back());
        } else {
            for (int j : records) {
                const std::vector<double>& w = s.weights[j][int(t)];
                if (std::accumulate(w.begin(), w.end(), 0.0) > 0) usable.push_back(&w);
            }
        }
        for (const std::vector<double>* w : usable) {
            const double total = std::accumulate(w->begin(), w->end(), 0.0);
            for (size_t v = 0; v < s.m(); ++v) p[v][t] += (*w)[v] / total / double(usable.size());
        }
    }
    return p;
}

IcMixture mixture_of(const Scenario& s, const std::vector<int>& records,
                     std::vector<const IcRecordTables*>& storage) {
    storage.clear();
    for (int j : records) storage.push_back(&s.tables[j]);
    return IcMixture(storage, s.fallback);
}

std::vector<PerIcType<double>> mixture_pmfs(const IcMixture& mixture, size_t m) {
    std::vector<PerIcType<double>> p(m);
    for (size_t v = 0; v < m; ++v) p[v] = mixture.pmfs(v);
    return p;
}

// Every subset of {F, U, B, C} that contains C, as sample counts (0 = disabled).
std::vector<IcSampleCounts> subsets_with_c(const IcSampleCounts& counts) {
    std::vector<IcSampleCounts> out;
    for (int bits = 0; bits < 8; ++bits) {
        IcSampleCounts n = counts;
        for (int t = 0; t < 3; ++t)
            if (!(bits & (1 << t))) n[IcType(t)] = 0;
        out.push_back(n);
    }
    return out;
}

std::string describe(const IcSampleCounts& n) {
    std::string s;
    for (IcType t : kIcTypes)
        if (n[t] > 0) s += ic_type_name(t);
    return s;
}

const std::vector<std::pair<std::string, IcWeighting>> kHeuristics = {
    {"alpha-max", {.heuristic = IcHeuristic::AlphaMax}},
    {"max (alpha = 1)", {.heuristic = IcHeuristic::AlphaMax, .alpha = {{1, 1, 1, 1}}}},
    {"balance", {.heuristic = IcHeuristic::Balance}},
    {"power", {.heuristic = IcHeuristic::Power, .beta = 2}},
};

IcWeightFunction weight_function(const IcWeighting& weighting) {
    return [weighting](const PerIcType<double>& p, const IcSampleCounts& n) {
        return ic_mis_weights(p, n, weighting);
    };
}

// Checks, for one shading point, that the mixture's pmf is the reference sampling probability,
// that the weights are a partition of unity where h > 0 (and 0 where a technique cannot draw),
// and that the exact expectation is sum h, for every heuristic and subset containing C.
void expect_unbiased(const Scenario& s, const std::vector<int>& records,
                     const IcSampleCounts& counts, const std::string& label) {
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, records, storage);
    const std::vector<PerIcType<double>> sampled = reference_sampling(s, records);
    const std::vector<PerIcType<double>> claimed = mixture_pmfs(mixture, s.m());
    for (size_t v = 0; v < s.m(); ++v)
        for (IcType t : kIcTypes)
            ASSERT_NEAR(claimed[v][t], sampled[v][t], 1e-12 * std::max(1.0, sampled[v][t]))
                << label << " v " << v << " " << ic_type_name(t);
    const double truth = std::accumulate(s.h.begin(), s.h.end(), 0.0);
    for (const IcSampleCounts& n : subsets_with_c(counts)) {
        for (const auto& [name, weighting] : kHeuristics) {
            const std::string where = label + ", " + describe(n) + ", " + name;
            for (size_t v = 0; v < s.m(); ++v) {
                if (!(s.h[v] > 0)) continue;
                const PerIcType<double> w = ic_mis_weights(claimed[v], n, weighting);
                double sum = 0;
                for (IcType t : kIcTypes) {
                    sum += w[t];
                    if (n[t] == 0 || claimed[v][t] == 0) {
                        ASSERT_EQ(w[t], 0.0) << where;
                    }
                }
                ASSERT_NEAR(sum, 1.0, 1e-12) << where << " v " << v;
            }
            const double expected =
                ic_expected_estimate(s.h, sampled, claimed, n, weight_function(weighting));
            if (truth == 0) {
                EXPECT_EQ(expected, 0.0) << where;
            } else {
                EXPECT_LT(relative_error(expected, truth), 1e-9)
                    << where << ": E = " << expected << ", sum h = " << truth;
            }
        }
    }
}

// a1: exact expectation over random VPL sets and record choices.
TEST(importance_cache_expectation, EqualsTheSumOfContributions) {
    Rng rng(StreamKey{12, 0, 1, 0});
    for (int trial = 0; trial < 40; ++trial) {
        const size_t m = trial % 10 == 0 ? 1 : 2 + size_t(uniform(rng) * 60);
        const bool all_f_zero = trial % 7 == 3;
        const int pool = 1 + int(uniform(rng) * 6);
        const Scenario s = random_scenario(rng, m, pool, all_f_zero);
        std::vector<int> records;  // R in 1..min(pool, kIcMaxRecords), random distinct records
        std::vector<int> all(pool);
        std::iota(all.begin(), all.end(), 0);
        for (int k = pool - 1; k > 0; --k) std::swap(all[k], all[size_t(uniform(rng) * (k + 1))]);
        const int r = 1 + int(uniform(rng) * std::min(pool, kIcMaxRecords));
        records.assign(all.begin(), all.begin() + r);
        const IcSampleCounts counts = {{1 + int(uniform(rng) * 4), 1 + int(uniform(rng) * 4),
                                        1 + int(uniform(rng) * 4), 1 + int(uniform(rng) * 4)}};
        expect_unbiased(s, records, counts,
                        "trial " + std::to_string(trial) + " (M " + std::to_string(m) + ", R " +
                            std::to_string(r) + (all_f_zero ? ", F all zero" : "") + ")");
    }
}

// The same with the alpha-max optimisation (importance_optimise.h): each record's tables keep,
// per VPL, only the technique alpha-max gives it at that record; the weights at x come from
// the optimised mixtures.
TEST(importance_cache_expectation, OptimisedTablesStayUnbiased) {
    Rng rng(StreamKey{13, 0, 1, 0});
    const PerIcType<double> alpha = {{1, 0.5, 0.5, 0.3}};
    for (int trial = 0; trial < 30; ++trial) {
        const size_t m = trial % 10 == 0 ? 1 : 2 + size_t(uniform(rng) * 60);
        const int pool = 1 + int(uniform(rng) * 5);
        Scenario s = random_scenario(rng, m, pool, trial % 7 == 3);
        std::vector<int> records(std::min(pool, 3));
        std::iota(records.begin(), records.end(), 0);
        for (const IcSampleCounts& n : subsets_with_c({{4, 4, 4, 4}})) {
            std::vector<IcRecordTables> optimised;
            for (const IcRecordTables& r : s.tables)
                optimised.push_back(optimise_record_tables(r, n, alpha));
            std::vector<const IcRecordTables*> storage;
            for (int j : records) storage.push_back(&optimised[j]);
            const IcMixture mixture(storage, s.fallback);
            // Sampling probabilities: the optimised tables' own pmfs (checked against the
            // sampler by the table tests); here s = P, the test is the partition of unity on
            // the union of supports, i.e. that no VPL lost every technique.
            const std::vector<PerIcType<double>> p = mixture_pmfs(mixture, m);
            const IcWeighting weighting{.heuristic = IcHeuristic::AlphaMax, .alpha = alpha};
            const double truth = std::accumulate(s.h.begin(), s.h.end(), 0.0);
            const double expected = ic_expected_estimate(s.h, p, p, n, weight_function(weighting));
            EXPECT_LT(relative_error(expected, truth), 1e-9)
                << "trial " << trial << ", " << describe(n);
            // No sample is wasted at a record: on its own tables every drawn VPL has weight 1.
            for (int j : records)
                for (size_t v = 0; v < m; ++v) {
                    PerIcType<double> own;
                    for (IcType t : kIcTypes) own[t] = optimised[j][t].pmf(v);
                    const PerIcType<double> w = ic_alpha_max_weights(own, n, alpha);
                    for (IcType t : kIcTypes)
                        if (own[t] > 0 && n[t] > 0) {
                            EXPECT_EQ(w[t], 1.0) << trial << " " << v;
                        }
                }
        }
    }
}

// Without C the optimisation could drop a VPL at every record; it refuses and returns the
// tables unchanged.
TEST(importance_cache_expectation, OptimisationWithoutCIsANoOp) {
    Rng rng(StreamKey{15, 0, 1, 0});
    const Scenario s = random_scenario(rng, 30, 1, false);
    const IcRecordTables same = optimise_record_tables(s.tables[0], {{4, 4, 4, 0}}, {{1, 1, 1, 1}});
    for (IcType t : kIcTypes)
        for (size_t v = 0; v < s.m(); ++v) EXPECT_EQ(same[t].pmf(v), s.tables[0][t].pmf(v));
}

// Planted errors: the comparison above must be able to fail. Each plants one mistake an
// integrator could make and asserts that the exact expectation then differs from sum h.
TEST(importance_cache_expectation, PlantedErrorsAreDetected) {
    Rng rng(StreamKey{14, 0, 1, 0});
    const Scenario s = random_scenario(rng, 40, 3, false);  // record 1 has an empty U table
    const std::vector<int> records = {0, 1, 2};
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, records, storage);
    ASSERT_EQ(mixture.usable_records(IcType::U), 2);
    const std::vector<PerIcType<double>> sampled = reference_sampling(s, records);
    const std::vector<PerIcType<double>> claimed = mixture_pmfs(mixture, s.m());
    const double truth = std::accumulate(s.h.begin(), s.h.end(), 0.0);
    const IcSampleCounts n = {{4, 4, 4, 4}};

    for (const auto& [name, weighting] : kHeuristics) {
        // Control: the honest estimator matches.
        EXPECT_LT(
            relative_error(
                ic_expected_estimate(s.h, sampled, claimed, n, weight_function(weighting)), truth),
            1e-9)
            << name;

        // 1. A weight that skips C: C's share is dropped (the VPL only C covers, and every VPL
        //    where C wins or shares, is lost).
        const IcWeightFunction skip_c = [&](const PerIcType<double>& p, const IcSampleCounts& k) {
            PerIcType<double> w = ic_mis_weights(p, k, weighting);
            w[IcType::C] = 0;
            return w;
        };
        const double without_c = ic_expected_estimate(s.h, sampled, claimed, n, skip_c);
        EXPECT_GT(relative_error(without_c, truth), 1e-3) << name << ": " << without_c;
        EXPECT_LT(without_c, truth) << name;

        // 2. A wrong pmf for one distribution, fed into the weights and the division: U's
        //    mixture taken as (1/R) sum over all R records, ignoring that record 1's U table
        //    is empty and never picked (the sampler draws with 1/R_U = 1/2, not 1/3).
        std::vector<PerIcType<double>> wrong_u = claimed;
        for (PerIcType<double>& p : wrong_u) p[IcType::U] *= 2.0 / 3.0;
        const double with_wrong_u =
            ic_expected_estimate(s.h, sampled, wrong_u, n, weight_function(weighting));
        EXPECT_GT(relative_error(with_wrong_u, truth), 1e-3) << name << ": " << with_wrong_u;
    }

    // 3. The sampler-side twin of 2: a sampler that picks among all R records and draws
    //    nothing from record 1's empty U table (probability of v: (R_U / R) P_U), while the
    //    estimator divides by the pmf over R_U records. U's share is 2/3 of what it should be.
    std::vector<PerIcType<double>> wasteful = sampled;
    for (PerIcType<double>& p : wasteful) p[IcType::U] *= 2.0 / 3.0;
    for (const auto& [name, weighting] : kHeuristics) {
        const double e =
            ic_expected_estimate(s.h, wasteful, claimed, n, weight_function(weighting));
        EXPECT_GT(relative_error(e, truth), 1e-3) << name << ": " << e;
    }

    // Positive control (section 0.3): weights from *proxy* pmfs with the same support (here
    // P_t^3 in place of P_t) are still a partition of unity, so the expectation is unchanged:
    // only the support of the weights and the divisor matter for bias.
    const IcWeightFunction proxy = [](const PerIcType<double>& p, const IcSampleCounts& k) {
        PerIcType<double> cubed;
        for (IcType t : kIcTypes) cubed[t] = p[t] * p[t] * p[t];
        return ic_balance_weights(cubed, k);
    };
    EXPECT_LT(relative_error(ic_expected_estimate(s.h, sampled, claimed, n, proxy), truth), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// MIS weights, written out

TEST(importance_cache_weights, HeuristicsFollowTheirDefinitions) {
    const PerIcType<double> p = {{0.02, 0.05, 0.01, 0.04}};
    const IcSampleCounts n = {{1, 2, 3, 4}};
    // Alpha-max, ordered: F (0.02) against max(0.5*0.05, 0.5*0.01, 0.3*0.04) = 0.025: no;
    // U (0.05) against max(0.005, 0.012): yes.
    EXPECT_EQ(ic_alpha_max_weights(p, n, {{1, 0.5, 0.5, 0.3}}), (PerIcType<double>{{0, 1, 0, 0}}));
    // alpha = 1 (max heuristic): the largest pmf wins; F disabled: U still wins.
    EXPECT_EQ(ic_alpha_max_weights(p, n, {{1, 1, 1, 1}}), (PerIcType<double>{{0, 1, 0, 0}}));
    EXPECT_EQ(ic_alpha_max_weights({{0.04, 0.05, 0.01, 0.04}}, n, {{1, 0.5, 0.5, 0.3}}),
              (PerIcType<double>{{1, 0, 0, 0}}));
    // Only C can draw: C.
    EXPECT_EQ(ic_alpha_max_weights({{0, 0, 0, 0.1}}, n, {{1, 0.5, 0.5, 0.3}}),
              (PerIcType<double>{{0, 0, 0, 1}}));
    // Nothing can draw: all 0.
    EXPECT_EQ(ic_alpha_max_weights({{0, 0, 0, 0}}, n, {{1, 0.5, 0.5, 0.3}}), PerIcType<double>{});
    // Balance and power with n_t P_t = 0.02, 0.10, 0.03, 0.16.
    const double q[4] = {0.02, 0.10, 0.03, 0.16};
    const double s1 = 0.31, s2 = 0.0004 + 0.01 + 0.0009 + 0.0256;
    const PerIcType<double> b = ic_balance_weights(p, n), w2 = ic_power_weights(p, n, 2);
    for (int t = 0; t < 4; ++t) {
        EXPECT_NEAR(b[IcType(t)], q[t] / s1, 1e-15);
        EXPECT_NEAR(w2[IcType(t)], q[t] * q[t] / s2, 1e-15);
    }
    // Disabled techniques (n = 0) get 0 and are left out of the sums.
    const PerIcType<double> bc = ic_balance_weights(p, {{0, 2, 0, 4}});
    EXPECT_EQ(bc[IcType::F], 0.0);
    EXPECT_NEAR(bc[IcType::U], 0.10 / 0.26, 1e-15);
    // Tiny pmfs (M = 1e5 mixtures): no underflow to 0/0.
    const PerIcType<double> tiny =
        ic_power_weights({{1e-170, 2e-170, 0, 1e-170}}, {{1, 1, 1, 1}}, 2);
    EXPECT_NEAR(tiny[IcType::U], 4.0 / 6.0, 1e-12);
    // The sample factor: w / (n P).
    const IcWeighting balance{.heuristic = IcHeuristic::Balance};
    EXPECT_NEAR(ic_sample_factor(IcType::U, p, n, balance), (0.10 / s1) / 0.10, 1e-12);
    EXPECT_EQ(ic_sample_factor(IcType::F, p, n, IcWeighting{}), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Sampling the mixture: chi-square against its pmf

// Draws `kSamples` VPLs of technique t from the mixture and compares with P_t(. | x).
ChiSquareResult chi_square_mixture(const IcMixture& mixture, IcType t, size_t m, uint64_t seed) {
    constexpr int kSamples = 1000000;
    std::vector<double> observed(m, 0.0), probability(m);
    Rng rng(StreamKey{seed, 0, 1, 0});
    for (int i = 0; i < kSamples; ++i) {
        const double u_record = rng.next_1d();
        observed[mixture.sample(t, u_record, next_double(rng))] += 1;
    }
    for (size_t v = 0; v < m; ++v) probability[v] = mixture.pmf(t, v);
    return chi_square_test_discrete(family, observed, probability, kSamples);
}

// Three records; record 1's U table is empty (so U mixes two records); F, B and C mix three.
CHI_SQUARE_TEST(family, importance_cache_mixture, SamplesFollowThePmf, 5) {
    Rng rng(StreamKey{21, 0, 1, 0});
    const Scenario s = random_scenario(rng, 50, 3, false);
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, {0, 1, 2}, storage);
    ASSERT_EQ(mixture.usable_records(IcType::U), 2);
    ASSERT_EQ(mixture.usable_records(IcType::F), 3);
    uint64_t seed = 100;
    for (IcType t : kIcTypes) {
        const ChiSquareResult r = chi_square_mixture(mixture, t, s.m(), seed++);
        EXPECT_TRUE(r.passed) << ic_type_name(t) << ": " << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-12);
    }
    // The fallback (no record): C over the mask.
    const IcMixture fallback({}, s.fallback);
    const ChiSquareResult r = chi_square_mixture(fallback, IcType::C, s.m(), seed);
    EXPECT_TRUE(r.passed) << r.message;
}

// The estimator as the integrator will run it (IcMixture::sample, then ic_sample_factor),
// averaged: its mean is sum h within 5 standard errors. Ties the sampler to the factor that the
// exact expectation checks.
TEST(importance_cache_estimator, MonteCarloMeanIsTheSum) {
    Rng scene_rng(StreamKey{51, 0, 1, 0});
    const Scenario s = random_scenario(scene_rng, 40, 3, false);
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, {0, 1, 2}, storage);
    const double truth = std::accumulate(s.h.begin(), s.h.end(), 0.0);
    const IcSampleCounts n = {{2, 1, 1, 1}};
    for (const auto& [name, weighting] : kHeuristics) {
        Rng rng(StreamKey{52, 0, 1, 0});
        constexpr int kEstimates = 100000;
        double sum = 0, sum_sq = 0;
        for (int e = 0; e < kEstimates; ++e) {
            double estimate = 0;
            for (IcType t : kIcTypes) {
                if (mixture.empty(t)) continue;
                for (int k = 0; k < n[t]; ++k) {
                    const double u_record = rng.next_1d();
                    const size_t v = mixture.sample(t, u_record, next_double(rng));
                    estimate += ic_sample_factor(t, mixture.pmfs(v), n, weighting) * s.h[v];
                }
            }
            sum += estimate;
            sum_sq += estimate * estimate;
        }
        const double mean = sum / kEstimates;
        const double standard_error =
            std::sqrt(std::max(0.0, sum_sq / kEstimates - mean * mean) / kEstimates);
        EXPECT_LT(std::abs(mean - truth), 5 * standard_error)
            << name << ": mean " << mean << ", sum h " << truth << ", standard error "
            << standard_error;
        EXPECT_GT(standard_error, 0.0) << name;
    }
}

// ---------------------------------------------------------------------------------------------
// Hard cases

// Records whose F, U and B tables are all zero: those techniques are empty at x (draw nothing,
// weight 0), C alone carries the estimate.
TEST(importance_cache_hard_cases, RecordsWithAllZeroDistributions) {
    Rng rng(StreamKey{31, 0, 1, 0});
    Scenario s = random_scenario(rng, 20, 3, false);
    for (auto& w : s.weights)
        for (auto& table : w) std::fill(table.begin(), table.end(), 0.0);
    s.build();
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, {0, 1, 2}, storage);
    for (IcType t : {IcType::F, IcType::U, IcType::B}) EXPECT_TRUE(mixture.empty(t));
    EXPECT_FALSE(mixture.empty(IcType::C));
    expect_unbiased(s, {0, 1, 2}, {{4, 4, 4, 4}}, "all-zero records");
}

TEST(importance_cache_hard_cases, SingleVpl) {
    Scenario s;
    s.h = {2.5};
    s.mask = {1};
    s.weights = {{std::vector<double>{0.0}, std::vector<double>{1.0}, std::vector<double>{3.0}}};
    s.build();
    std::vector<const IcRecordTables*> storage;
    const IcMixture mixture = mixture_of(s, {0}, storage);
    EXPECT_TRUE(mixture.empty(IcType::F));
    for (IcType t : {IcType::U, IcType::B, IcType::C}) {
        EXPECT_EQ(mixture.pmf(t, 0), 1.0);
        EXPECT_EQ(mixture.sample(t, 0.99, 0.99), 0u);
    }
    expect_unbiased(s, {0}, {{1, 1, 1, 1}}, "single VPL");
}

// No record within reach: the lookup returns none and the mixture is C over all VPLs.
TEST(importance_cache_hard_cases, NoRecordInRangeFallsBackToC) {
    const std::vector<IcRecordPoint> points = {{{10, 0, 0}, {0, 0, 1}}, {{0, 10, 0}, {0, 0, 1}}};
    const IcLookupSettings settings{.count = 3, .lambda = 0.05, .max_distance = 1.0};
    const IcNeighbours none =
        ic_nearest_records_brute_force(points, {0, 0, 0}, {0, 0, 1}, settings);
    EXPECT_EQ(none.count, 0);
    EXPECT_EQ(IcRecordTree(points).nearest({0, 0, 0}, {0, 0, 1}, settings).count, 0);
    // No records at all.
    EXPECT_EQ(
        IcRecordTree(std::vector<IcRecordPoint>{}).nearest({0, 0, 0}, {0, 0, 1}, settings).count,
        0);

    Rng rng(StreamKey{32, 0, 1, 0});
    const Scenario s = random_scenario(rng, 30, 2, false);
    const IcMixture fallback({}, s.fallback);
    EXPECT_EQ(fallback.record_count(), 0);
    const double count = std::accumulate(s.mask.begin(), s.mask.end(), 0.0);
    for (size_t v = 0; v < s.m(); ++v) {
        EXPECT_EQ(fallback.pmf(IcType::C, v), s.mask[v] ? 1 / count : 0.0);
        for (IcType t : {IcType::F, IcType::U, IcType::B}) EXPECT_EQ(fallback.pmf(t, v), 0.0);
    }
    expect_unbiased(s, {}, {{4, 4, 4, 4}}, "no record");
}

// 1e5 VPLs, the mixture of three records: a VPL that one record weights 1e-7 of the mean keeps
// the exact mixture pmf.
TEST(importance_cache_hard_cases, LargeVplCountKeepsTinyEntries) {
    constexpr size_t kM = 100000, kTiny = 77777;
    std::vector<uint8_t> mask(kM, 1);
    std::vector<std::array<std::vector<double>, 3>> weights(3);
    for (int j = 0; j < 3; ++j)
        for (auto& w : weights[j]) w.assign(kM, 1.0 + j);
    weights[0][0][kTiny] = 1e-7;  // F of record 0
    weights[1][0][kTiny] = 0.0;   // F of record 1
    weights[2][0][kTiny] = 0.0;   // F of record 2
    std::vector<IcRecordTables> tables;
    for (const auto& w : weights) tables.push_back(make_record_tables(w[0], w[1], w[2], mask));
    const ImportanceTable fallback = conservative_table(mask);
    const std::vector<const IcRecordTables*> pointers = {&tables[0], &tables[1], &tables[2]};
    const IcMixture mixture(pointers, fallback);
    const double expected = (1e-7 / (double(kM - 1) + 1e-7)) / 3;
    EXPECT_LT(relative_error(mixture.pmf(IcType::F, kTiny), expected), 1e-4);
    EXPECT_EQ(mixture.pmf(IcType::C, kTiny), 1.0 / double(kM));
    // Reachable: record 0 picked (u_record < 1/3), u inside the entry's interval.
    const double total0 = double(kM - 1) + 1e-7;
    EXPECT_EQ(mixture.sample(IcType::F, 0.1, (double(kTiny) + 0.5e-7) / total0), kTiny);
    // The weights stay a partition of unity at these magnitudes.
    const PerIcType<double> w = ic_power_weights(mixture.pmfs(kTiny), {{4, 4, 4, 4}}, 2);
    EXPECT_NEAR(w[IcType::F] + w[IcType::U] + w[IcType::B] + w[IcType::C], 1.0, 1e-12);
    EXPECT_GT(w[IcType::F], 0.0);
}

// ---------------------------------------------------------------------------------------------
// Record lookup

TEST(importance_cache_lookup, DistanceFollowsTheFormula) {
    const IcRecordPoint r{{1, 2, 2}, {0, 0, 1}};
    EXPECT_NEAR(ic_record_distance({0, 0, 0}, {0, 0, 1}, r, 0.25), 3.0, 1e-12);
    EXPECT_NEAR(ic_record_distance({0, 0, 0}, {1, 0, 0}, r, 0.25), 3.25, 1e-12);
    // A normal facing the other way is the same surface orientation (importance_lookup.h).
    EXPECT_NEAR(ic_record_distance({0, 0, 0}, {0, 0, -1}, r, 0.25), 3.0, 1e-12);
    EXPECT_NEAR(ic_record_distance({0, 0, 0}, {0, 0.6f, -0.8f}, r, 0.25), 3 + 0.25 * std::sqrt(0.2),
                1e-6);
    // Rounding that pushes n . n above 1 does not give NaN.
    EXPECT_NEAR(ic_record_distance({1, 2, 2}, {0, 0, 1.0000001f}, r, 0.25), 0.0, 1e-12);
    EXPECT_DOUBLE_EQ(ic_default_lambda(4.0), 2.0);
}

// The default weight scales with the scene (lambda = 0.5 D, importance_lookup.h): the same
// scene in other units chooses the same records, and a record on another surface (normal at 90
// degrees) is as far as one half a diameter away. With lambda = 0.5 / D the choice below flips
// between the scales; with the signed cosine, for the floor normal facing down.
TEST(importance_cache_lookup, DefaultWeightChoosesTheSameRecordsAtEveryScale) {
    // x on a floor (normal +z) at a wall's foot; record 0 on the wall, near; record 1 on the
    // floor, farther.
    const std::vector<IcRecordPoint> unit_points = {{{0, 0.1f, 0.05f}, {0, -1, 0}},
                                                    {{0, -0.3f, 0}, {0, 0, 1}}};
    const Vec3 x(0, 0, 0);
    const double diameter = 2.0;
    // The floor's own normal may face away from the record's viewer: the same choice.
    for (const Vec3 n_x : {Vec3(0, 0, 1), Vec3(0, 0, -1)})
        for (const double scale : {0.001, 1.0, 1000.0}) {
            std::vector<IcRecordPoint> points = unit_points;
            for (IcRecordPoint& p : points) p.position = p.position * float(scale);
            const IcLookupSettings settings{.count = 1,
                                            .lambda = ic_default_lambda(diameter * scale)};
            const IcNeighbours near = ic_nearest_records_brute_force(points, x, n_x, settings);
            ASSERT_EQ(near.count, 1) << scale;
            EXPECT_EQ(near.index[0], 1u) << scale;  // the floor's record
            EXPECT_NEAR(near.distance[0], 0.3 * scale, 1e-6 * scale);
        }
}

TEST(importance_cache_lookup, NormalTermAndTiesDecide) {
    // Two records at the same distance: the one with the matching normal is nearer.
    const std::vector<IcRecordPoint> points = {{{1, 0, 0}, {0, 1, 0}},
                                               {{-1, 0, 0}, {0, 0, 1}},
                                               {{-1, 0, 0}, {0, 0, 1}},
                                               {{0, 3, 0}, {0, 0, 1}}};
    const IcLookupSettings settings{.count = 2, .lambda = 0.1};
    const IcNeighbours best =
        ic_nearest_records_brute_force(points, {0, 0, 0}, {0, 0, 1}, settings);
    ASSERT_EQ(best.count, 2);
    EXPECT_EQ(best.index[0], 1u);  // exact tie with record 2: the lower index first
    EXPECT_EQ(best.index[1], 2u);
    EXPECT_EQ(best.distance[0], 1.0);
}

// A shading point behind a record's surface (the far side of a thin wall) does not use it: the
// record's tables hold nothing for the VPLs that light the far side (importance_lookup.h).
// Within the slack (a point on the record's own plane, or slightly behind it) it does.
TEST(importance_cache_lookup, RecordsBehindTheShadingPointAreNotUsed) {
    // A wall z in [0, 0.1]: record 0 on its near face (normal +z, toward its viewer), record 1
    // on the floor of the far side, farther from x than record 0.
    const std::vector<IcRecordPoint> points = {{{0, 0, 0.1f}, {0, 0, 1}},
                                               {{1, 0, -0.3f}, {0, 1, 0}}};
    const Vec3 x(0.2f, 0, -0.05f), n_x(0, 1, 0);
    const IcLookupSettings settings{.count = 2, .lambda = 0.05};
    for (const IcNeighbours& near : {ic_nearest_records_brute_force(points, x, n_x, settings),
                                     IcRecordTree(points).nearest(x, n_x, settings)}) {
        ASSERT_EQ(near.count, 1);
        EXPECT_EQ(near.index[0], 1u);
    }
    // Without the test both are used, the wall's record first (it is nearer).
    IcLookupSettings any = settings;
    any.behind_slack = std::numeric_limits<double>::infinity();
    const IcNeighbours both = ic_nearest_records_brute_force(points, x, n_x, any);
    ASSERT_EQ(both.count, 2);
    EXPECT_EQ(both.index[0], 0u);
    // On the record's plane, and 5 % of the distance behind it: in front (within the slack).
    EXPECT_TRUE(ic_record_faces(points[0], {3, 1, 0.1f}, settings.behind_slack));
    EXPECT_TRUE(ic_record_faces(points[0], {1, 0, 0.05f}, settings.behind_slack));
    EXPECT_FALSE(ic_record_faces(points[0], {1, 0, -0.1f}, settings.behind_slack));
    // A record in a medium (no normal) faces everything.
    EXPECT_TRUE(ic_record_faces({{0, 0, 0}, {0, 0, 0}}, {0, 0, -1}, settings.behind_slack));
}

// The k-d tree returns exactly the brute force's records (same order) on random records,
// including duplicated positions (ties), a plane of records and limited range.
TEST(importance_cache_lookup, TreeMatchesBruteForce) {
    Rng rng(StreamKey{41, 0, 1, 0});
    auto unit = [&] {
        const double z = 2 * uniform(rng) - 1, phi = 2 * M_PI * uniform(rng);
        const double r = std::sqrt(1 - z * z);
        return Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z));
    };
    for (int layout = 0; layout < 3; ++layout) {
        std::vector<IcRecordPoint> points;
        for (int i = 0; i < 1500; ++i) {
            Vec3 p(float(uniform(rng) * 10), float(uniform(rng) * 4), float(uniform(rng) * 6));
            if (layout == 1) p.z = 0;  // all on a plane
            points.push_back({p, unit()});
            if (layout == 2 && i % 5 == 0) points.push_back(points.back());  // duplicates
        }
        const IcRecordTree tree(points);
        for (int q = 0; q < 400; ++q) {
            const Vec3 x(float(uniform(rng) * 14 - 2), float(uniform(rng) * 8 - 2),
                         float(uniform(rng) * 10 - 2));
            const Vec3 n = unit();
            IcLookupSettings settings{.count = 1 + q % kIcMaxRecords,
                                      .lambda = ic_default_lambda(12.5)};
            if (q % 4 == 0) settings.lambda = 2.0;  // a strong normal term
            if (q % 3 == 0) settings.max_distance = 1.0 + uniform(rng);
            const IcNeighbours a = ic_nearest_records_brute_force(points, x, n, settings);
            const IcNeighbours b = tree.nearest(x, n, settings);
            ASSERT_EQ(a.count, b.count) << layout << " " << q;
            for (int k = 0; k < a.count; ++k) {
                ASSERT_EQ(a.index[k], b.index[k]) << layout << " " << q << " " << k;
                ASSERT_EQ(a.distance[k], b.distance[k]);
                if (k > 0) {
                    ASSERT_LE(a.distance[k - 1], a.distance[k]);
                }
            }
            if (settings.max_distance == INFINITY) {
                ASSERT_EQ(a.count, std::min<int>(settings.count, int(points.size())));
            }
        }
    }
}

}  // namespace
}  // namespace render::testing
