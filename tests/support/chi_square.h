#pragma once

// Chi-square goodness-of-fit tests in the style of Mitsuba's ChiSquareTest: draw many samples
// from a sampling routine, histogram them, and compare against the expected counts of the
// density that the routine claims. Every variant below ends in one routine
// (chi_square_from_counts): cells are sorted by expected count and the smallest pooled until
// each group has >= 5 expected samples; a sample in a cell of expected count 0 fails outright;
// the p-value is the chi-square survival function Q(dof / 2, statistic / 2) with
// dof = groups - 1. Fixed seeds make every run identical; a wrong pdf or sampler fails with
// p ~ 0.
//
// Significance and the Sidak correction -- the rule:
//   * Every test file that runs chi-square checks defines ONE family at namespace scope,
//         ChiSquareFamily family;
//     before its tests, and passes it to every chi-square call.
//   * Every TEST that runs chi-square checks is written CHI_SQUARE_TEST(family, Suite, Name, n)
//     instead of TEST(Suite, Name), declaring the n checks it runs (a TEST_P declares with a
//     ChiSquareDeclaration: checks per instance times instances).
//   * The family's total is the sum of its declarations, complete once static initialisation
//     is over (CTest runs every test case in its own process, so the total cannot depend on
//     which tests run). Each check rejects at the Sidak-corrected level
//         alpha = 1 - (1 - 0.01)^(1 / total),
//     so the whole file has a 1 % false-positive rate.
//   * A check in a test that declared none, or one more than the test declared, fails the test
//     (and the check); a test that ends having run fewer checks than it declared fails too.
//     So adding a check without declaring it cannot silently shift alpha.

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/math/vec.h"
#include "core/sampling/rng.h"

namespace render::testing {

struct ChiSquareResult {
    bool passed = false;
    double p_value = 0;
    double statistic = 0;
    int degrees_of_freedom = 0;
    double alpha = 0;         // the Sidak-corrected level the p-value was compared with
    double pdf_integral = 0;  // integral of the pdf over the domain, should be <= 1
    std::string message;      // the worst cells, for failure output
};

// The chi-square checks of one test file (see the rule above).
class ChiSquareFamily {
  public:
    explicit ChiSquareFamily(double significance = 0.01);
    ~ChiSquareFamily();
    ChiSquareFamily(const ChiSquareFamily&) = delete;
    ChiSquareFamily& operator=(const ChiSquareFamily&) = delete;

    // `test` is "Suite.Name" as gtest names it; a parameterised test is declared without its
    // instantiation prefix and parameter suffix ("Suite.Name" for "Prefix/Suite.Name/param"),
    // and every instance may run `checks` checks.
    void declare(const std::string& test, int checks, int instances = 1);

    int total() const { return total_; }
    double significance() const { return significance_; }
    // Sidak-corrected level of one check: 1 - (1 - significance)^(1 / total).
    double alpha() const;

    // Counts one check of the running test (gtest's current test) and returns an error when
    // that exceeds the test's declaration. The chi-square functions call it; a test never
    // needs to.
    std::optional<std::string> record_check();
    // An error when `full_name` (as gtest reports it) declared more checks than it ran.
    std::optional<std::string> unfinished(const std::string& full_name) const;

    // Checks declared per run of `full_name` (0 when it declared none).
    int declared(const std::string& full_name) const;

  private:
    class Listener;  // reports unfinished() at the end of every test

    Listener* listener_ = nullptr;  // owned by gtest's listener list
    double significance_;
    int total_ = 0;
    std::map<std::string, int> declared_;  // checks per instance
    std::map<std::string, int> ran_;       // by full test name
};

// A static registrar: declares `checks` checks of `test` in `family` at static initialisation.
struct ChiSquareDeclaration {
    ChiSquareDeclaration(ChiSquareFamily& family, const char* test, int checks, int instances = 1) {
        family.declare(test, checks, instances);
    }
};

// TEST(suite, name) that runs `checks` chi-square checks of `family`.
#define CHI_SQUARE_TEST(family, suite, name, checks)                                       \
    const ::render::testing::ChiSquareDeclaration chi_square_declaration_##suite##_##name( \
        family, #suite "." #name, checks);                                                 \
    TEST(suite, name)

struct ChiSquareOptions {
    int resolution_x = 32;
    int resolution_y = 32;
    int sample_count = 1000000;
    uint64_t seed = 1;
};

// The shared core: observed and expected counts per cell, pooled, tested at family.alpha();
// `cell_name` describes a cell index for the failure message. Records one check of `family`.
ChiSquareResult chi_square_from_counts(ChiSquareFamily& family, const std::vector<double>& observed,
                                       const std::vector<double>& expected,
                                       const std::function<std::string(size_t)>& cell_name);

// Discrete: observed counts per cell against exact cell probabilities (sample_count draws).
// pdf_integral is the sum of the probabilities.
ChiSquareResult chi_square_test_discrete(ChiSquareFamily& family,
                                         const std::vector<double>& observed,
                                         const std::vector<double>& probability, int sample_count);

// Domain [x0, x1] x [y0, y1]. `sample` draws one point (or nothing, when sampling fails) from
// two uniform numbers and an extra one for lobe selection; `pdf` is the claimed density w.r.t.
// dx dy. Cells are integrated by composite 2-point Gauss-Legendre (interior nodes only).
struct Rect {
    double x0, x1, y0, y1;
};
ChiSquareResult chi_square_test_2d(ChiSquareFamily& family,
                                   const std::function<std::optional<Vec2>(Rng&)>& sample,
                                   const std::function<double(Vec2)>& pdf, Rect domain,
                                   const ChiSquareOptions& options);

// Unit directions, histogrammed over (phi, cos theta) so that every cell has the same solid
// angle; `pdf` is w.r.t. solid angle.
ChiSquareResult chi_square_test_sphere(ChiSquareFamily& family,
                                       const std::function<std::optional<Vec3>(Rng&)>& sample,
                                       const std::function<double(const Vec3&)>& pdf,
                                       const ChiSquareOptions& options);

// One dimension: [x0, x1] in `cells` cells, expected counts from integrate_graded (so a spike
// at `peak` of width ~h is integrated correctly). A sample outside [x0, x1] fails the test.
struct ChiSquareOptions1d {
    int cells = 64;
    int sample_count = 1000000;
    uint64_t seed = 1;
    std::optional<double> peak;
    double h = 0;
};
ChiSquareResult chi_square_test_1d(ChiSquareFamily& family,
                                   const std::function<double(Rng&)>& sample,
                                   const std::function<double(double)>& pdf, double x0, double x1,
                                   const ChiSquareOptions1d& options);

// Integral of f over [a, b]: composite 3-point Gauss-Legendre on pieces graded geometrically
// toward `peak` (pieces [peak + h 2^k, peak + h 2^(k+1)] on both sides), so that a spike of
// width ~h is resolved however wide the range.
double integrate_graded(const std::function<double(double)>& f, double a, double b,
                        std::optional<double> peak = std::nullopt, double h = 0);

// Regularised upper incomplete gamma Q(a, x); the chi-square survival function is
// Q(dof / 2, statistic / 2). Exposed for its own test.
double regularized_gamma_q(double a, double x);

}  // namespace render::testing
