// Every warp of core/sampling/warp.h against its density: chi-square tests of the samples
// (tests/support/chi_square.h) and a numerical check that the density integrates to one.

#include "core/sampling/warp.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <optional>

#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

using DirectionSampler = std::function<Vec3(Vec2)>;
using DirectionPdf = std::function<double(const Vec3&)>;

void expect_passes(const ChiSquareResult& r) {
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3) << r.message;
}

// Directions on the whole sphere, histogrammed by chi_square_test_sphere.
ChiSquareResult test_sphere(const DirectionSampler& sample, const DirectionPdf& pdf) {
    return chi_square_test_sphere(
        family, [&](Rng& rng) -> std::optional<Vec3> { return sample(rng.next_2d()); }, pdf,
        ChiSquareOptions());
}

// Directions in the cap z >= z_min only (for narrow lobes, so that the histogram resolves
// them): chart (phi, z) on [0, 2 pi) x [z_min, 1], where d omega = d phi dz. Samples outside
// the cap are dropped, which the expected counts account for (they integrate the pdf over the
// cap only); callers check that the cap holds all but a negligible part of the mass.
ChiSquareResult test_cap(const DirectionSampler& sample, const DirectionPdf& pdf, float z_min) {
    auto sample_2d = [&](Rng& rng) -> std::optional<Vec2> {
        Vec3 w = sample(rng.next_2d());
        if (w.z < z_min) return std::nullopt;
        float phi = std::atan2(w.y, w.x);
        if (phi < 0) phi += 2.0f * kPi;
        return Vec2(phi, w.z);
    };
    // The harness also evaluates the pdf on the domain's edge z = z_min, where hemisphere and
    // cone densities jump to 0: evaluate there by continuity from inside the cap.
    auto pdf_2d = [&](Vec2 p) {
        float z = std::clamp(p.y, z_min + 1e-6f, 1.0f), r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        return pdf(Vec3(r * std::cos(p.x), r * std::sin(p.x), z));
    };
    return chi_square_test_2d(family, sample_2d, pdf_2d, Rect{0.0, 2.0 * M_PI, z_min, 1.0},
                              ChiSquareOptions());
}

// Integral of a solid-angle pdf over the sphere, midpoint rule in (phi, z).
double integrate_sphere(const DirectionPdf& pdf, int n_phi = 64, int n_z = 20000) {
    double sum = 0;
    for (int i = 0; i < n_phi; ++i) {
        double phi = 2.0 * M_PI * (i + 0.5) / n_phi;
        for (int j = 0; j < n_z; ++j) {
            double z = -1.0 + 2.0 * (j + 0.5) / n_z, r = std::sqrt(1.0 - z * z);
            sum += pdf(Vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
        }
    }
    return sum * (2.0 * M_PI / n_phi) * (2.0 / n_z);
}

// Integral of an area pdf over [x0, x1] x [y0, y1], midpoint rule.
double integrate_plane(const std::function<double(Vec2)>& pdf, double x0, double x1, double y0,
                       double y1, int n = 2000) {
    double sum = 0, hx = (x1 - x0) / n, hy = (y1 - y0) / n;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            sum += pdf(Vec2(float(x0 + (i + 0.5) * hx), float(y0 + (j + 0.5) * hy)));
    return sum * hx * hy;
}

// Every sampled direction is unit length and has a positive, finite density.
void expect_well_formed(const DirectionSampler& sample, const DirectionPdf& pdf) {
    Rng rng(StreamKey{7, 0, 1, 0});
    const Vec2 corners[] = {{0, 0},
                            {kOneMinusEpsilon, 0},
                            {0, kOneMinusEpsilon},
                            {kOneMinusEpsilon, kOneMinusEpsilon},
                            {0.5f, 0.5f}};
    for (int i = 0; i < 10000 + 5; ++i) {
        Vec2 u = i < 5 ? corners[i] : rng.next_2d();
        Vec3 w = sample(u);
        ASSERT_TRUE(is_finite(w)) << "u = " << u.x << ", " << u.y;
        ASSERT_NEAR(length(w), 1.0f, 1e-5f);
        double p = pdf(w);
        ASSERT_TRUE(std::isfinite(p));
        // A sample exactly on the domain's boundary (u = 0) may have density 0.
        if (i >= 5) {
            ASSERT_GT(p, 0.0) << "w = " << w;
        }
    }
}

CHI_SQUARE_TEST(family, Warp, UniformHemisphere, 1) {
    // Histogrammed over the hemisphere only, where the density is smooth (on the whole sphere
    // it jumps to 0 at z = 0).
    DirectionSampler s = warp::square_to_uniform_hemisphere;
    DirectionPdf p = [](const Vec3& w) { return warp::square_to_uniform_hemisphere_pdf(w); };
    expect_well_formed(s, p);
    expect_passes(test_cap(s, p, 0.0f));
    EXPECT_NEAR(integrate_sphere(p), 1.0, 1e-4);
}

CHI_SQUARE_TEST(family, Warp, CosineHemisphere, 1) {
    DirectionSampler s = warp::square_to_cosine_hemisphere;
    DirectionPdf p = [](const Vec3& w) { return warp::square_to_cosine_hemisphere_pdf(w); };
    expect_well_formed(s, p);
    expect_passes(test_sphere(s, p));
    EXPECT_NEAR(integrate_sphere(p), 1.0, 1e-4);
}

CHI_SQUARE_TEST(family, Warp, UniformSphere, 1) {
    DirectionSampler s = warp::square_to_uniform_sphere;
    DirectionPdf p = [](const Vec3&) { return warp::square_to_uniform_sphere_pdf(); };
    expect_well_formed(s, p);
    expect_passes(test_sphere(s, p));
    EXPECT_NEAR(integrate_sphere(p), 1.0, 1e-4);
}

// Every cone is histogrammed over its own cap z >= cos_max, where its density is smooth (see
// UniformHemisphere); all samples fall inside the cap.
CHI_SQUARE_TEST(family, Warp, UniformCone, 3) {
    for (float cos_max : {-0.5f, 0.3f, 0.95f}) {
        SCOPED_TRACE(cos_max);
        DirectionSampler s = [=](Vec2 u) { return warp::square_to_uniform_cone(u, cos_max); };
        DirectionPdf p = [=](const Vec3& w) {
            return warp::square_to_uniform_cone_pdf(w, cos_max);
        };
        expect_well_formed(s, p);
        expect_passes(test_cap(s, p, cos_max));
        EXPECT_NEAR(integrate_sphere(p), 1.0, 2e-3);
    }
}

CHI_SQUARE_TEST(family, Warp, PhongLobe, 3) {
    // (exponent, cap): for exponent 90 the cap z >= 0.8 holds all but 0.8^91 ~ 1e-9 of the
    // mass, and resolves the lobe far better than the whole-sphere histogram.
    for (auto [exponent, z_min] : {std::pair{1.0f, -1.0f}, {10.0f, -1.0f}, {90.0f, 0.8f}}) {
        SCOPED_TRACE(exponent);
        DirectionSampler s = [=](Vec2 u) { return warp::square_to_phong_lobe(u, exponent); };
        DirectionPdf p = [=](const Vec3& w) { return warp::square_to_phong_lobe_pdf(w, exponent); };
        expect_well_formed(s, p);
        expect_passes(z_min > -1 ? test_cap(s, p, z_min) : test_sphere(s, p));
        EXPECT_NEAR(integrate_sphere(p), 1.0, 1e-3);
    }
}

CHI_SQUARE_TEST(family, Warp, ConcentricDisk, 1) {
    // Chart (phi, r^2) on [0, 2 pi) x [0, 1]: dA = r dr dphi = 1/2 d(r^2) dphi, so the
    // chart density is pdf(p) / 2 and has no jump inside the domain (unlike a Cartesian grid
    // cut by the disk's rim).
    auto sample = [](Rng& rng) -> std::optional<Vec2> {
        Vec2 p = warp::square_to_uniform_disk_concentric(rng.next_2d());
        float phi = std::atan2(p.y, p.x);
        if (phi < 0) phi += 2.0f * kPi;
        return Vec2(phi, p.x * p.x + p.y * p.y);
    };
    auto pdf = [](Vec2 c) {
        float r = std::sqrt(std::clamp(c.y, 0.0f, 1.0f));
        Vec2 p(r * std::cos(c.x), r * std::sin(c.x));
        return 0.5 * warp::square_to_uniform_disk_pdf(p * 0.999999f);
    };
    expect_passes(chi_square_test_2d(family, sample, pdf, Rect{0.0, 2.0 * M_PI, 0.0, 1.0},
                                     ChiSquareOptions()));

    auto cartesian_pdf = [](Vec2 p) { return double(warp::square_to_uniform_disk_pdf(p)); };
    EXPECT_NEAR(integrate_plane(cartesian_pdf, -1, 1, -1, 1), 1.0, 5e-3);
    for (Vec2 u : {Vec2(0, 0), Vec2(0.5f, 0.5f), Vec2(kOneMinusEpsilon, kOneMinusEpsilon)}) {
        Vec2 p = warp::square_to_uniform_disk_concentric(u);
        EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y));
        EXPECT_LE(p.x * p.x + p.y * p.y, 1.0f + 1e-6f);
    }
}

CHI_SQUARE_TEST(family, Warp, UniformTriangle, 1) {
    // Chart (a, t) = (b1 + b2, b2 / (b1 + b2)) on [0, 1]^2, with |d(b1, b2) / d(a, t)| = a:
    // the chart density pdf(b) * a is smooth (no jump along the hypotenuse inside a cell).
    auto sample = [](Rng& rng) -> std::optional<Vec2> {
        Vec2 b = warp::square_to_uniform_triangle(rng.next_2d());
        float a = b.x + b.y;
        return Vec2(a, a > 0 ? b.y / a : 0.0f);
    };
    auto pdf = [](Vec2 c) {
        float a = c.x, t = c.y;
        Vec2 b(a * (1 - t), a * t);
        return double(warp::square_to_uniform_triangle_pdf(b * 0.999999f)) * a;
    };
    expect_passes(
        chi_square_test_2d(family, sample, pdf, Rect{0.0, 1.0, 0.0, 1.0}, ChiSquareOptions()));

    auto barycentric_pdf = [](Vec2 b) { return double(warp::square_to_uniform_triangle_pdf(b)); };
    EXPECT_NEAR(integrate_plane(barycentric_pdf, 0, 1, 0, 1), 1.0, 5e-3);
    Rng rng(StreamKey{3, 0, 1, 0});
    for (int i = 0; i < 10000; ++i) {
        Vec2 b = warp::square_to_uniform_triangle(rng.next_2d());
        ASSERT_GE(b.x, 0.0f);
        ASSERT_GE(b.y, 0.0f);
        ASSERT_LE(b.x + b.y, 1.0f + 1e-6f);
    }
}

}  // namespace
}  // namespace render::testing
