// The chi-square toolkit of tests/support/chi_square.h: the survival function, that every
// variant (discrete, 1-D, 2-D, sphere) rejects a wrong density and accepts the right one, and
// the Sidak bookkeeping of ChiSquareFamily, including that a test running more or fewer checks
// than it declared is caught.

#include "tests/support/chi_square.h"

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "core/sampling/warp.h"

namespace render::testing {
namespace {

ChiSquareFamily family;

TEST(ChiSquare, GammaQMatchesKnownValues) {
    // Chi-square survival with 2 dof is exp(-x/2); with 1 dof it is erfc(sqrt(x/2)).
    EXPECT_NEAR(regularized_gamma_q(1.0, 1.5), std::exp(-1.5), 1e-12);
    EXPECT_NEAR(regularized_gamma_q(0.5, 2.0), std::erfc(std::sqrt(2.0)), 1e-12);
    // For integer a, Q(a, x) is the Poisson CDF: exp(-x) sum_{k<a} x^k / k!.
    for (auto [a, x] : {std::pair{50, 50.0}, std::pair{10, 3.0}, std::pair{4, 20.0}}) {
        double term = std::exp(-x), poisson = 0;
        for (int k = 0; k < a; ++k) poisson += term, term *= x / (k + 1);
        EXPECT_NEAR(regularized_gamma_q(a, x), poisson, 1e-12 + 1e-10 * poisson);
    }
}

CHI_SQUARE_TEST(family, ChiSquare, RejectsAWrongPdf, 1) {
    // Cosine-weighted samples tested against the uniform hemisphere pdf must fail.
    ChiSquareOptions options;
    options.sample_count = 200000;
    auto sample = [](Rng& rng) -> std::optional<Vec3> {
        return warp::square_to_cosine_hemisphere(rng.next_2d());
    };
    auto wrong_pdf = [](const Vec3& w) {
        return double(warp::square_to_uniform_hemisphere_pdf(w));
    };
    ChiSquareResult result = chi_square_test_sphere(family, sample, wrong_pdf, options);
    EXPECT_FALSE(result.passed) << result.message;
    EXPECT_LT(result.p_value, 1e-6);
}

// Discrete: a fair die passes; a die loaded by 2 % between two faces (1e6 throws, ~9
// standard deviations on each) fails with p < 1e-6; a face of probability 0 that shows up fails
// outright.
CHI_SQUARE_TEST(family, ChiSquare, DiscreteAcceptsTheRightAndRejectsAWrongProbability, 3) {
    const int n = 1000000;
    std::vector<double> observed(6, 0.0);
    Rng rng(StreamKey{5, 0, 1, 0});
    for (int i = 0; i < n; ++i) observed[std::min(int(rng.next_1d() * 6), 5)] += 1;
    const std::vector<double> fair(6, 1.0 / 6.0);
    ChiSquareResult right = chi_square_test_discrete(family, observed, fair, n);
    EXPECT_TRUE(right.passed) << right.message;
    EXPECT_NEAR(right.pdf_integral, 1.0, 1e-12);

    std::vector<double> loaded = fair;
    loaded[0] += 0.02 / 6, loaded[1] -= 0.02 / 6;
    ChiSquareResult wrong = chi_square_test_discrete(family, observed, loaded, n);
    EXPECT_FALSE(wrong.passed) << wrong.message;
    EXPECT_LT(wrong.p_value, 1e-6) << wrong.message;

    std::vector<double> impossible = {0.2, 0.2, 0.2, 0.2, 0.2, 0.0};
    ChiSquareResult zero = chi_square_test_discrete(family, observed, impossible, n);
    EXPECT_FALSE(zero.passed);
    EXPECT_NE(zero.message.find("integrates to 0"), std::string::npos) << zero.message;
}

// 1-D: x = u^2 has density 1 / (2 sqrt(x)) on (0, 1] (a spike at 0, resolved by the graded
// integration); the uniform density must be rejected, and a sample outside the domain fails.
CHI_SQUARE_TEST(family, ChiSquare, OneDimensionalAcceptsTheRightAndRejectsAWrongPdf, 3) {
    auto sample = [](Rng& rng) {
        double u = rng.next_1d();
        return u * u;
    };
    auto pdf = [](double x) { return x > 0 ? 0.5 / std::sqrt(x) : 0.0; };
    ChiSquareOptions1d options;
    options.seed = 6;
    options.peak = 0.0;
    options.h = 1e-9;  // the unresolved mass below h is sqrt(h) ~ 3e-5
    ChiSquareResult right = chi_square_test_1d(family, sample, pdf, 0.0, 1.0, options);
    EXPECT_TRUE(right.passed) << right.message;
    EXPECT_NEAR(right.pdf_integral, 1.0, 1e-4) << right.message;

    ChiSquareResult wrong = chi_square_test_1d(
        family, sample, [](double) { return 1.0; }, 0.0, 1.0, options);
    EXPECT_FALSE(wrong.passed) << wrong.message;
    EXPECT_LT(wrong.p_value, 1e-6) << wrong.message;

    ChiSquareResult outside = chi_square_test_1d(
        family, [](Rng& rng) { return 2.0 * rng.next_1d(); }, [](double) { return 1.0; }, 0.0, 1.0,
        options);
    EXPECT_FALSE(outside.passed);
    EXPECT_NE(outside.message.find("outside the domain"), std::string::npos) << outside.message;
}

// 2-D: uniform points on the unit square pass.
CHI_SQUARE_TEST(family, ChiSquare, TwoDimensionalAcceptsTheRightPdf, 1) {
    ChiSquareOptions options;
    options.sample_count = 200000;
    options.seed = 7;
    ChiSquareResult r = chi_square_test_2d(
        family, [](Rng& rng) -> std::optional<Vec2> { return rng.next_2d(); },
        [](Vec2) { return 1.0; }, Rect{0, 1, 0, 1}, options);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-9);
}

// ------------------------------------------------------------------------------------------
// The family's bookkeeping. These tests use their own local families (a local family stops
// watching tests when it is destroyed).

std::string current_test() {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    return std::string(info->test_suite_name()) + "." + info->name();
}

std::vector<double> fair_coin_counts() {
    return {500.0, 500.0};
}
const std::vector<double> kFairCoin = {0.5, 0.5};

TEST(ChiSquareFamily, TotalIsTheSumOfDeclarationsAndAlphaIsSidak) {
    ChiSquareFamily local;
    EXPECT_EQ(local.total(), 0);
    local.declare("A.One", 3);
    local.declare("B.Param", 2, /*instances=*/5);
    ChiSquareDeclaration registrar(local, "C.Two", 4);
    EXPECT_EQ(local.total(), 3 + 2 * 5 + 4);
    EXPECT_NEAR(local.alpha(), 1.0 - std::pow(0.99, 1.0 / 17.0), 1e-15);
    EXPECT_EQ(local.declared("A.One"), 3);
    EXPECT_EQ(local.declared("C.Two"), 4);
    // A parameterised test's instances are found under their declaration.
    EXPECT_EQ(local.declared("Prefix/B.Param/case_7"), 2);
    EXPECT_EQ(local.declared("B.Param/3"), 2);
    EXPECT_EQ(local.declared("A.Other"), 0);
    // The file's own family: the declarations above this test's.
    EXPECT_EQ(family.total(), 1 + 3 + 3 + 1);
}

TEST(ChiSquareFamily, ResultReportsTheCorrectedAlpha) {
    ChiSquareFamily local;
    local.declare(current_test(), 1);
    local.declare("Other.Test", 9);
    ChiSquareResult r = chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.alpha, 1.0 - std::pow(0.99, 0.1), 1e-15);
    EXPECT_EQ(r.p_value, 1.0);
    EXPECT_FALSE(local.unfinished(current_test()));
}

TEST(ChiSquareFamily, MoreChecksThanDeclaredFail) {
    ChiSquareFamily local;
    local.declare(current_test(), 1);
    ChiSquareResult first = chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000);
    EXPECT_TRUE(first.passed) << first.message;
    ChiSquareResult second;
    EXPECT_NONFATAL_FAILURE(
        second = chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000),
        "runs chi-square check 2 but declared 1");
    EXPECT_FALSE(second.passed);  // even though the data fit
}

TEST(ChiSquareFamily, UndeclaredCheckFails) {
    ChiSquareFamily local;
    local.declare("Some.OtherTest", 5);
    ChiSquareResult r;
    EXPECT_NONFATAL_FAILURE(
        r = chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000), "declared 0");
    EXPECT_FALSE(r.passed);
}

TEST(ChiSquareFamily, FewerChecksThanDeclaredAreReported) {
    ChiSquareFamily local;
    local.declare(current_test(), 2);
    ASSERT_TRUE(local.unfinished(current_test()));
    EXPECT_NE(local.unfinished(current_test())->find("declared 2 chi-square checks but ran 0"),
              std::string::npos);
    chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000);
    ASSERT_TRUE(local.unfinished(current_test()));
    chi_square_test_discrete(local, fair_coin_counts(), kFairCoin, 1000);
    EXPECT_FALSE(local.unfinished(current_test()));
    // A test that declared nothing and ran nothing is complete.
    EXPECT_FALSE(local.unfinished("Some.OtherTest"));
}

// A test that ends having run fewer checks than it declared fails through the family's gtest
// listener, which needs a whole test run: this test runs the probe below in a child process
// (this same executable) and expects it to fail with the family's message.
ChiSquareFamily probe_family;  // its own family, so that the probe leaves `family` alone

// Never runs on its own (DISABLED_); only as the child of the test after it.
CHI_SQUARE_TEST(probe_family, ChiSquareProbe, DISABLED_DeclaresTwoRunsOne, 2) {
    ChiSquareResult r = chi_square_test_discrete(probe_family, fair_coin_counts(), kFairCoin, 1000);
    EXPECT_TRUE(r.passed) << r.message;
}

TEST(ChiSquareFamily, TestEndingWithFewerChecksThanDeclaredFails) {
    char self[4096];
    const ssize_t length = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
    ASSERT_GT(length, 0);
    self[length] = 0;
    const std::string command = std::string("'") + self +
                                "' --gtest_also_run_disabled_tests "
                                "--gtest_filter=ChiSquareProbe.DISABLED_DeclaresTwoRunsOne 2>&1";
    FILE* child = ::popen(command.c_str(), "r");
    ASSERT_NE(child, nullptr);
    std::string output;
    char buffer[4096];
    while (size_t n = std::fread(buffer, 1, sizeof(buffer), child)) output.append(buffer, n);
    const int status = ::pclose(child);
    ASSERT_TRUE(WIFEXITED(status)) << output;
    EXPECT_EQ(WEXITSTATUS(status), 1) << output;
    EXPECT_NE(output.find("declared 2 chi-square checks but ran 1"), std::string::npos) << output;
    EXPECT_NE(output.find("[  FAILED  ] ChiSquareProbe.DISABLED_DeclaresTwoRunsOne ("),
              std::string::npos)
        << output;
}

}  // namespace
}  // namespace render::testing
