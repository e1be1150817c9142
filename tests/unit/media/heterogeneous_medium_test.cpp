// The heterogeneous medium's estimators against closed forms, with fixed seeds and tolerances in
// standard errors: ratio tracking's transmittance (constant and linear-ramp grids, with Russian
// roulette forced), delta tracking's distance density (chi-square) and pass probability, chromatic
// spectral tracking's per-channel expectations and its documented weight bounds, and the
// extremes (a very dense and a very thin medium).

#include "core/media/heterogeneous_medium.h"

#include <gtest/gtest.h>

#include "core/integrators/medium_segment.h"

#include <cmath>
#include <functional>
#include <memory>
#include <optional>

#include "core/media/constant_volume.h"
#include "core/media/grid_volume.h"
#include "core/media/heterogeneous_medium_factory.h"
#include "core/media/isotropic_phase.h"
#include "tests/support/chi_square.h"
#include "tests/support/statistics.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;
constexpr double kSigmas = 5.0;  // tolerance of every mean, in standard errors

// A grid of n voxels along x (1 along y and z) whose channel c samples the linear function
// a[c] + b[c] u at the voxel centres u = (i + 1/2) / n, over the world box [0, L]^3.
// Trilinear interpolation reproduces the line between the first and last centres and is
// constant (clamped) within half a voxel of the faces.
struct Ramp {
    int n;
    Rgb a, b;
    float length;
    Rgb voxel(int i) const { return a + b * ((float(i) + 0.5f) / float(n)); }
    // sigma_t(u) (before scale) and its integral from 0 to u, per channel, in double.
    double value(int c, double u) const {
        const double h = 0.5 / n;
        return a[c] + b[c] * std::clamp(u, h, 1.0 - h);
    }
    double integral(int c, double u) const {  // of value over [0, u], u in [0, 1]
        const double h = 0.5 / n;
        const double v0 = a[c] + b[c] * h, v1 = a[c] + b[c] * (1 - h);
        if (u <= h) return v0 * u;
        const double mid_end = std::min(u, 1.0 - h);
        double s = v0 * h + a[c] * (mid_end - h) + 0.5 * b[c] * (mid_end * mid_end - h * h);
        if (u > 1 - h) s += v1 * (u - (1 - h));
        return s;
    }
    std::shared_ptr<GridVolume> volume(bool grey) const {
        VolumeGridData d;
        d.xres = n, d.yres = 1, d.zres = 1, d.channels = grey ? 1 : 3;
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < d.channels; ++c) d.values.push_back(voxel(i)[c]);
        return std::make_shared<GridVolume>(std::move(d), Transform::scale(Vec3(length)));
    }
};

// Rays along +x through the middle of the box, starting `before` ahead of it (empty space).
struct Line {
    Ramp ramp;
    float scale = 1;
    float before = 0.3f;
    Ray ray() const {
        return Ray(Vec3(-before, 0.5f * ramp.length, 0.5f * ramp.length), Vec3(1, 0, 0));
    }
    // Optical depth from the ray origin to distance t, channel c.
    double tau(int c, double t) const {
        const double u = std::clamp((t - before) / ramp.length, 0.0, 1.0);
        return scale * ramp.length * ramp.integral(c, u);
    }
    double sigma(int c, double t) const {
        const double u = (t - before) / ramp.length;
        return u < 0 || u > 1 ? 0.0 : scale * ramp.value(c, u);
    }
    double tr(int c, double t) const { return std::exp(-tau(c, t)); }
};

std::unique_ptr<HeterogeneousMedium> make_medium(const Line& s, bool grey, const Rgb& albedo,
                                                 std::array<int, 3> majorant_res = {0, 0, 0}) {
    return std::make_unique<HeterogeneousMedium>(s.ramp.volume(grey),
                                                 std::make_shared<ConstantVolume>(albedo), s.scale,
                                                 std::make_shared<IsotropicPhase>(), majorant_res);
}

using Mean = MeanAccumulator;

void expect_mean(const Mean& m, double expected, const std::string& what) {
    // A floor on the standard error for estimators with (almost) no variance.
    const double tolerance = kSigmas * std::max(m.standard_error(), 1e-7);
    EXPECT_NEAR(m.mean(), expected, tolerance)
        << what << ": mean " << m.mean() << " +- " << m.standard_error() << " (standard error)";
}

// (d) Ratio tracking's mean transmittance matches exp(-integral of sigma_t).
TEST(HeterogeneousMedium, RatioTrackingMatchesAnalyticTransmittance) {
    struct Case {
        const char* name;
        Line setup;
        std::array<int, 3> majorant_res;
    };
    const Case cases[] = {
        {"constant", {Ramp{8, Rgb(1.5f), Rgb(0.0f), 1.0f}}, {0, 0, 0}},
        {"ramp", {Ramp{16, Rgb(0.2f), Rgb(3.0f), 2.0f}}, {0, 0, 0}},
        // One majorant cell: many ratio steps per ray, so Russian roulette kicks in.
        {"ramp, one majorant cell", {Ramp{16, Rgb(0.2f), Rgb(3.0f), 2.0f}}, {1, 1, 1}},
        {"chromatic ramp",
         {Ramp{32, Rgb(0.1f, 2.0f, 0.5f), Rgb(1.0f, -1.5f, 4.0f), 1.0f}},
         {1, 1, 1}},
    };
    for (const Case& k : cases) {
        const bool grey =
            k.setup.ramp.a.r == k.setup.ramp.a.g && k.setup.ramp.b.r == k.setup.ramp.b.g;
        auto medium = make_medium(k.setup, grey, Rgb(0.5f), k.majorant_res);
        for (float t_max : {0.2f, 0.3f + 0.6f * k.setup.ramp.length, 100.0f}) {
            Mean m[3];
            Rng rng(StreamKey{17, 0, 1, uint64_t(t_max * 1000)});
            for (int i = 0; i < 200000; ++i) {
                const Rgb tr = medium->transmittance(k.setup.ray(), t_max, rng);
                for (int c = 0; c < 3; ++c) {
                    ASSERT_TRUE(tr[c] >= 0 && tr[c] <= 1) << tr;
                    m[c].add(tr[c]);
                }
            }
            for (int c = 0; c < 3; ++c)
                expect_mean(m[c], k.setup.tr(c, t_max),
                            std::string(k.name) + ", t_max " + std::to_string(t_max) +
                                ", channel " + std::to_string(c));
        }
    }
}

// (e) Delta tracking's distances follow sigma_t(t) T(t) (chi-square over the segment inside
// the grid, a dummy second dimension), it passes with probability T(t_max), and for grey
// media its weights are those of classic delta tracking: the albedo, or exactly 1.
CHI_SQUARE_TEST(family, HeterogeneousMedium, DeltaTrackingDistanceDistribution, 3) {
    const Line setups[] = {
        {Ramp{8, Rgb(1.2f), Rgb(0.0f), 1.0f}},
        {Ramp{16, Rgb(0.3f), Rgb(2.5f), 1.5f}},
        {Ramp{16, Rgb(2.5f), Rgb(-2.3f), 1.5f}, 1.0f, 0.0f},
    };
    for (const Line& s : setups) {
        const float t_end = s.before + 0.8f * s.ramp.length;  // ends inside the grid
        auto medium = make_medium(s, true, Rgb(0.8f));
        ChiSquareOptions options;
        options.resolution_x = 64;
        options.resolution_y = 1;
        options.sample_count = 400000;
        long passes = 0;
        auto sample = [&](Rng& rng) -> std::optional<Vec2> {
            const MediumSample ms = medium->sample(s.ray(), t_end, rng);
            if (!ms.scattered) {
                ++passes;
                EXPECT_EQ(ms.weight, Rgb(1.0f));
                EXPECT_EQ(ms.t, t_end);
                return std::nullopt;
            }
            EXPECT_EQ(ms.weight, Rgb(0.8f));
            EXPECT_GT(ms.t, s.before);
            return Vec2(ms.t, rng.next_1d());
        };
        auto pdf = [&](Vec2 p) { return s.sigma(0, p.x) * s.tr(0, p.x); };
        const ChiSquareResult r =
            chi_square_test_2d(family, sample, pdf, Rect{s.before, t_end, 0.0, 1.0}, options);
        EXPECT_TRUE(r.passed) << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0 - s.tr(0, t_end), 1e-4);
        // The pass count is binomial.
        const double p = s.tr(0, t_end), n = options.sample_count;
        EXPECT_NEAR(double(passes) / n, p, kSigmas * std::sqrt(p * (1 - p) / n));
    }
}

// (f) Chromatic spectral tracking: E[weight_c 1{scatter in [a, b]}] = albedo_c (T_c(a) - T_c(b))
// and E[weight_c 1{pass}] = T_c(t_max), per channel; every weight is within the documented
// bound (3 albedo on scattering, 3 on passing).
TEST(HeterogeneousMedium, SpectralTrackingIsUnbiasedWithBoundedWeights) {
    const Rgb albedo(0.9f, 0.5f, 0.7f);
    const Line setups[] = {
        {Ramp{16, Rgb(0.2f, 3.0f, 1.0f), Rgb(2.0f, -2.5f, 0.5f), 1.0f}},
        // Very different channels: one transparent, one dense.
        {Ramp{8, Rgb(0.0f, 12.0f, 0.5f), Rgb(0.0f, 0.0f, 0.0f), 1.0f}},
    };
    for (const Line& s : setups) {
        auto medium = make_medium(s, false, albedo);
        const float t_end = s.before + s.ramp.length + 0.5f;  // passes beyond the grid
        constexpr int kBins = 5;
        const double lo = s.before, hi = s.before + s.ramp.length;
        Mean bins[kBins][3], pass[3];
        float worst_scatter = 0, worst_pass = 0;
        Rng rng(StreamKey{23, 0, 1, 0});
        for (int i = 0; i < 400000; ++i) {
            const MediumSample ms = medium->sample(s.ray(), t_end, rng);
            ASSERT_TRUE(ms.weight.is_finite());
            int bin = -1;
            if (ms.scattered) {
                bin = std::clamp(int((ms.t - lo) / (hi - lo) * kBins), 0, kBins - 1);
                for (int c = 0; c < 3; ++c)
                    worst_scatter = std::max(worst_scatter, ms.weight[c] / (3.0f * albedo[c]));
            } else {
                EXPECT_EQ(ms.t, t_end);
                worst_pass = std::max(worst_pass, ms.weight.max() / 3.0f);
            }
            for (int c = 0; c < 3; ++c) {
                for (int b = 0; b < kBins; ++b) bins[b][c].add(b == bin ? ms.weight[c] : 0.0);
                pass[c].add(ms.scattered ? 0.0 : ms.weight[c]);
            }
        }
        EXPECT_LE(worst_scatter, 1.0f + 1e-4f);
        EXPECT_LE(worst_pass, 1.0f + 1e-4f);
        for (int c = 0; c < 3; ++c) {
            for (int b = 0; b < kBins; ++b) {
                const double a = lo + (hi - lo) * b / kBins, e = lo + (hi - lo) * (b + 1) / kBins;
                expect_mean(bins[b][c], albedo[c] * (s.tr(c, a) - s.tr(c, e)),
                            "bin " + std::to_string(b) + ", channel " + std::to_string(c));
            }
            expect_mean(pass[c], s.tr(c, t_end), "pass, channel " + std::to_string(c));
        }
    }
}

// (g) Russian roulette: a very dense medium (sigma_t * size >= 1e3) gives transmittance ~0
// quickly and without NaN; a very thin one (sigma_t * t < 1e-6) gives 1 to float precision.
TEST(HeterogeneousMedium, ExtremeDensities) {
    const Line dense[] = {
        {Ramp{8, Rgb(2000.0f), Rgb(0.0f), 1.0f}},
        {Ramp{16, Rgb(1000.0f), Rgb(3000.0f, 5000.0f, 1000.0f), 1.0f}},
    };
    for (const Line& s : dense) {
        auto medium = make_medium(s, false, Rgb(0.9f), {1, 1, 1});
        Mean m;
        Rng rng(StreamKey{31, 0, 1, 0});
        for (int i = 0; i < 20000; ++i) {
            const Rgb tr = medium->transmittance(s.ray(), 10.0f, rng);
            ASSERT_TRUE(tr.is_finite());
            ASSERT_TRUE(tr.max() <= 1 && tr.r >= 0 && tr.g >= 0 && tr.b >= 0);
            m.add(tr.max());
            const MediumSample ms = medium->sample(s.ray(), 10.0f, rng);
            ASSERT_TRUE(ms.weight.is_finite());
            ASSERT_TRUE(ms.scattered);
            ASSERT_LT(ms.t, s.before + 0.05f);
        }
        // exp(-1000) is 0 in any precision; RR keeps the mean unbiased, so it must be tiny.
        EXPECT_LT(m.mean(), 1e-3);
    }

    Line thin{Ramp{8, Rgb(1e-7f), Rgb(0.0f), 1.0f}};
    auto medium = make_medium(thin, true, Rgb(0.9f));
    Mean m;
    Rng rng(StreamKey{37, 0, 1, 0});
    for (int i = 0; i < 200000; ++i) m.add(medium->transmittance(thin.ray(), 10.0f, rng).r);
    EXPECT_NEAR(m.mean(), 1.0, 2e-6);
    EXPECT_NEAR(medium->probability_pass(thin.ray(), 10.0f), 1.0f, 1e-6f);
}

// The MIS approximations: exact for a constant grid, close for a ramp, consistent (the pass
// probability starts at 1 and the scattering density integrates to 1 - P(pass)).
TEST(HeterogeneousMedium, PdfApproximation) {
    const Line s{Ramp{8, Rgb(1.5f), Rgb(0.0f), 1.0f}};
    auto medium = make_medium(s, true, Rgb(0.5f));
    for (float t : {0.1f, 0.5f, 0.9f, 1.25f, 5.0f}) {
        EXPECT_NEAR(medium->probability_pass(s.ray(), t), s.tr(0, t), 1e-5) << t;
        EXPECT_NEAR(medium->pdf_scatter_l(s.ray(), t), s.sigma(0, t) * s.tr(0, t), 1e-5) << t;
    }
    const Line ramp{Ramp{32, Rgb(0.2f), Rgb(3.0f), 2.0f}};
    auto m2 = make_medium(ramp, true, Rgb(0.5f));
    EXPECT_EQ(m2->probability_pass(ramp.ray(), 0.0f), 1.0f);
    double integral = 0;
    const int n = 20000;
    const float t_end = ramp.before + ramp.ramp.length;
    for (int i = 0; i < n; ++i)
        integral += m2->pdf_scatter_l(ramp.ray(), t_end * (i + 0.5f) / n) * t_end / n;
    EXPECT_NEAR(integral, 1.0 - m2->probability_pass(ramp.ray(), t_end), 0.02);
    EXPECT_NEAR(m2->probability_pass(ramp.ray(), t_end), ramp.tr(0, t_end),
                0.05 * ramp.tr(0, t_end));
}

TEST(HeterogeneousMedium, FactoryReadsScaleAndValidates) {
    const SourceLocation here{"scene.xml", 7};
    auto sigma = std::make_shared<ConstantVolume>(Rgb(2.0f));
    {
        Properties p("medium", "heterogeneous", here);
        p.set("scale", 3.0f, here);
        auto m = make_heterogeneous_medium(p, sigma, nullptr, nullptr);
        p.check_all_used();
        EXPECT_EQ(m->sigma_t(Vec3(0.0f)), Rgb(6.0f));
        EXPECT_EQ(m->sigma_s(Vec3(0.0f)), Rgb(6.0f * 0.75f));  // Mitsuba's default albedo
        EXPECT_FALSE(m->is_homogeneous());
    }
    {
        Properties p("medium", "heterogeneous", here);
        p.set("scale", -1.0f, here);
        EXPECT_THROW(make_heterogeneous_medium(p, sigma, nullptr, nullptr), SceneError);
    }
    {
        Properties p("medium", "heterogeneous", here);
        EXPECT_THROW(make_heterogeneous_medium(
                         p, sigma, std::make_shared<ConstantVolume>(Rgb(1.5f)), nullptr),
                     SceneError);
    }
}

// A grid too dense for tracking to step through (a scale of 1e30 kept a worker on one ray for
// ever) is refused at load with the parameter's location; one just below the bound loads. The
// grid is the unit cube (diagonal sqrt(3)) with sigma_t up to 1.
TEST(HeterogeneousMedium, FactoryRefusesGridsTooDenseToTrack) {
    const SourceLocation here{"scene.xml", 9};
    const std::shared_ptr<GridVolume> grid = Ramp{4, Rgb(1.0f), Rgb(0.0f), 1.0f}.volume(true);
    auto medium_with_scale = [&](float scale) {
        Properties p("medium", "heterogeneous", here);
        p.set("scale", scale, here);
        return make_heterogeneous_medium(p, grid, nullptr, nullptr);
    };
    EXPECT_NO_THROW(medium_with_scale(5e4f));  // 8.7e4 mean free paths across
    for (float scale : {1e5f, 1e30f}) {
        try {
            medium_with_scale(scale);
            ADD_FAILURE() << "scale " << scale << " was accepted";
        } catch (const SceneError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("scene.xml:9"), std::string::npos) << what;
            EXPECT_NE(what.find("mean free paths"), std::string::npos) << what;
        }
    }
    // A constant (unbounded) volume has no extent to step through here: any finite density.
    Properties p("medium", "heterogeneous", here);
    p.set("scale", 1e30f, here);
    EXPECT_NO_THROW(make_heterogeneous_medium(p, std::make_shared<ConstantVolume>(Rgb(1.0f)),
                                              nullptr, nullptr));
}

// The bidirectional family's MIS (medium_segment.h) takes each segment's distance densities from
// the medium's proxies, evaluated by every technique that can sample the segment: from whichever
// end it is traced, a segment must give the same two numbers, and the density of sampling its
// start from its end must use sigma_t at the start. On a ramp (sigma_t growing along the ray),
// a segment between two medium vertices traced forward and backward gives swapped densities,
// and their ratio is sigma_t(end) / sigma_t(start). (With sigma_t at the end for both, bpt and
// vcm were 6 % bright on the smoke scene.)
TEST(HeterogeneousMedium, SegmentDensitiesAreTheSameFromEitherEnd) {
    // sigma_t from 1 to 4 across a box of length 1, 64 voxels.
    const Line s{Ramp{64, Rgb(1.0f), Rgb(3.0f), 1.0f}, 1.0f, 0.0f};
    auto medium = make_medium(s, true, Rgb(0.5f));
    const Ray forward = s.ray();
    const float a = 0.2f, b = 0.9f;  // the two vertices, along the ray
    const Vec3 pa = forward.at(a), pb = forward.at(b);
    SegmentDensityBuilder from_a(true);
    from_a.add_piece(medium.get(), Ray(pa, forward.direction), b - a);
    const SegmentDensities d_ab = from_a.finish(true);
    SegmentDensityBuilder from_b(true);
    from_b.add_piece(medium.get(), Ray(pb, -forward.direction), b - a);
    const SegmentDensities d_ba = from_b.finish(true);
    EXPECT_NEAR(d_ab.toward_end, d_ba.toward_start, 1e-5 * d_ab.toward_end);
    EXPECT_NEAR(d_ab.toward_start, d_ba.toward_end, 1e-5 * d_ab.toward_start);
    const double sigma_a = s.sigma(0, a), sigma_b = s.sigma(0, b);
    ASSERT_GT(sigma_b, 1.5 * sigma_a);
    EXPECT_NEAR(d_ab.toward_end / d_ab.toward_start, sigma_b / sigma_a, 1e-3 * sigma_b / sigma_a);
}

}  // namespace
}  // namespace render::testing
