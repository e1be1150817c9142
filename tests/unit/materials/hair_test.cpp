// pbrt-v4's hair BSDF (core/materials/hair.h), tested as pbrt-v4 tests it and more:
//   - white furnace: without absorption, the fibre scatters all light, integral f cos = 1 for
//     random wo, h and roughness, by uniform sampling and by the BSDF's own sampling;
//   - without absorption every sampling weight is exactly 1 (the term pdfs are the Ap);
//   - with absorption, uniform and importance-sampled estimates agree;
//   - the density integrates to one and the sampled directions follow it (chi-square);
//   - sample(), f() and pdf_w() agree; Importance mode is the adjoint;
//   - the scattering function S = f |cos theta_i| is reciprocal where the model is (h = 0, no
//     scale tilt, |sin theta_i| = |sin theta_o|: Ap, Mp and Np are then symmetric);
//   - the material's parameters, and h from the hit's v.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/base/properties.h"
#include "core/materials/bsdf_factory.h"
#include "core/materials/hair.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/chi_square.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

using testing::ChiSquareDeclaration;
using testing::ChiSquareFamily;
using testing::ChiSquareOptions;
using testing::ChiSquareResult;
using testing::MeanAccumulator;

HairParams white(float beta_m, float beta_n, float alpha) {
    HairParams p;
    p.sigma_a = Rgb(0.0f);
    p.beta_m = beta_m;
    p.beta_n = beta_n;
    p.alpha = alpha;
    return p;
}

bool close(float a, float b, float rel) {
    return std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + 1e-7f;
}

// pbrt-v4's WhiteFurnace test with uniform sphere sampling, over its grid of roughnesses and
// also with the scale tilt. Each estimate uses fresh wo, h and wi per sample; the model's
// normalisation is exact up to the asymptotic log I0 (< 1e-3), so the tolerance is 5 standard
// errors plus 2e-3.
TEST(Hair, WhiteFurnaceUniformSampling) {
    Rng rng(StreamKey{34, 0, 1, 0});
    for (float alpha : {0.0f, 2.0f})
        for (float beta_m = 0.1f; beta_m < 1; beta_m += 0.2f)
            for (float beta_n = 0.1f; beta_n < 1; beta_n += 0.2f) {
                SCOPED_TRACE("beta_m " + std::to_string(beta_m) + " beta_n " +
                             std::to_string(beta_n) + " alpha " + std::to_string(alpha));
                MeanAccumulator sum;
                for (int i = 0; i < 200000; ++i) {
                    const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
                    // Half the samples take h from wo (Mitsuba's): random wo, random h.
                    const float h = -1 + 2 * rng.next_1d();
                    const HairBsdf hair =
                        i % 2 ? HairBsdf(white(beta_m, beta_n, alpha), h)
                              : HairBsdf(white(beta_m, beta_n, alpha), HairOffset::FromDirection);
                    const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
                    sum.add(hair.f(wo, wi, TransportMode::Radiance).average() * std::abs(wi.z) /
                            warp::square_to_uniform_sphere_pdf());
                }
                EXPECT_NEAR(sum.mean(), 1.0, 5 * sum.standard_error() + 2e-3);
            }
}

// pbrt-v4's SamplingWeights: without absorption f cos / pdf is the sum of the Ap, 1, for every
// sample (float rounding only). That also makes the sampled white furnace exactly 1.
TEST(Hair, SamplingWeightsAreOneWithoutAbsorption) {
    Rng rng(StreamKey{34, 0, 2, 0});
    int checked = 0;
    for (float alpha : {0.0f, 2.0f})
        for (float beta_m = 0.1f; beta_m < 1; beta_m += 0.2f)
            for (float beta_n = 0.1f; beta_n < 1; beta_n += 0.2f)
                for (int i = 0; i < 2000; ++i) {
                    const HairBsdf hair(white(beta_m, beta_n, alpha), -1 + 2 * rng.next_1d());
                    const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
                    const float u_lobe = rng.next_1d();
                    const auto s = hair.sample(wo, u_lobe, rng.next_2d(), TransportMode::Radiance);
                    if (!s) continue;
                    ++checked;
                    for (int c = 0; c < 3; ++c)
                        ASSERT_NEAR(s->weight[c], 1.0f, 1e-3f)
                            << "wo " << wo << " wi " << s->wi << " " << hair.to_string();
                }
    // Only wo or wi exactly in the normal plane (z = 0) may fail to sample.
    EXPECT_GT(checked, 99000);
}

// pbrt-v4's SamplingConsistency: with absorption, the integral of f cos estimated by uniform
// sampling and by sample() agree. Tolerance: 5 standard errors of the difference.
TEST(Hair, SampledAndUniformEstimatesAgree) {
    HairParams p;
    p.sigma_a = Rgb(0.25f, 0.6f, 1.4f);
    Rng rng(StreamKey{34, 0, 3, 0});
    for (float beta_m : {0.2f, 0.5f, 0.8f})
        for (float beta_n : {0.2f, 0.6f}) {
            p.beta_m = beta_m;
            p.beta_n = beta_n;
            SCOPED_TRACE("beta_m " + std::to_string(beta_m) + " beta_n " + std::to_string(beta_n));
            const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
            MeanAccumulator uniform[3], sampled[3];
            for (int i = 0; i < 200000; ++i) {
                const HairBsdf hair(p, -1 + 2 * rng.next_1d());
                const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
                const Rgb f = hair.f(wo, wi, TransportMode::Radiance) *
                              (std::abs(wi.z) / warp::square_to_uniform_sphere_pdf());
                const float u_lobe = rng.next_1d();
                const auto s = hair.sample(wo, u_lobe, rng.next_2d(), TransportMode::Radiance);
                for (int c = 0; c < 3; ++c) {
                    uniform[c].add(f[c]);
                    sampled[c].add(s ? s->weight[c] : 0.0);
                }
            }
            for (int c = 0; c < 3; ++c) {
                const double se =
                    std::hypot(uniform[c].standard_error(), sampled[c].standard_error());
                EXPECT_NEAR(uniform[c].mean(), sampled[c].mean(), 5 * se) << "channel " << c;
                // Absorption removes light: the albedo is below 1 and above 0.
                EXPECT_LT(sampled[c].mean(), 1.0);
                EXPECT_GT(sampled[c].mean(), 0.0);
            }
        }
}

// The density integrates to one over the sphere (every sample is a direction): uniform-sphere
// estimate, 5 standard errors.
TEST(Hair, DensityIntegratesToOne) {
    HairParams p;
    p.sigma_a = Rgb(0.4f, 0.8f, 1.6f);
    Rng rng(StreamKey{34, 0, 4, 0});
    for (float beta_m : {0.15f, 0.3f, 0.7f})
        for (float h : {-0.9f, 0.0f, 0.5f}) {
            p.beta_m = beta_m;
            const HairBsdf hair(p, h);
            const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
            MeanAccumulator integral;
            for (int i = 0; i < 400000; ++i) {
                const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
                integral.add(hair.pdf_w(wo, wi).forward / warp::square_to_uniform_sphere_pdf());
            }
            EXPECT_NEAR(integral.mean(), 1.0, 5 * integral.standard_error() + 2e-3)
                << hair.to_string() << " wo " << wo;
        }
}

Vec3 direction(float sin_theta_x, float phi) {
    // x along the fibre: sin theta = x; phi in the (y, z) plane.
    const float c = std::sqrt(std::max(0.0f, 1 - sin_theta_x * sin_theta_x));
    return {sin_theta_x, c * std::cos(phi), c * std::sin(phi)};
}

// sample() returns what f() and pdf_w() report, in both modes; everything finite.
TEST(Hair, SampleAgreesWithEvalAndPdf) {
    HairParams p;
    p.sigma_a = Rgb(0.2f, 0.5f, 1.1f);
    Rng rng(StreamKey{34, 0, 5, 0});
    int checked = 0;
    for (int i = 0; i < 20000; ++i) {
        p.beta_m = 0.05f + 0.9f * rng.next_1d();
        p.beta_n = 0.05f + 0.9f * rng.next_1d();
        const float h = -1 + 2 * rng.next_1d();
        const HairBsdf hair = i % 2 ? HairBsdf(p, h) : HairBsdf(p, HairOffset::FromDirection);
        const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
        for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
            const float u_lobe = rng.next_1d();
            const auto s = hair.sample(wo, u_lobe, rng.next_2d(), mode);
            if (!s) continue;
            ++checked;
            ASSERT_NEAR(length(s->wi), 1.0f, 1e-4f);
            ASSERT_TRUE(s->weight.is_finite());
            const BsdfPdf pdf = hair.pdf_w(wo, s->wi);
            ASSERT_TRUE(close(pdf.forward, s->pdf_w.forward, 1e-4f));
            ASSERT_TRUE(close(pdf.reverse, s->pdf_w.reverse, 1e-4f));
            ASSERT_TRUE(close(hair.pdf_w(s->wi, wo).forward, pdf.reverse, 1e-4f));
            const Rgb expected = hair.f(wo, s->wi, mode) * (std::abs(s->wi.z) / pdf.forward);
            for (int c = 0; c < 3; ++c) ASSERT_TRUE(close(expected[c], s->weight[c], 1e-4f));
            ASSERT_EQ(s->lobe,
                      wo.z * s->wi.z > 0 ? kLobeGlossyReflection : kLobeGlossyTransmission);
        }
    }
    EXPECT_GT(checked, 39000);
    // Edge directions: along the fibre, in the normal plane, at the poles.
    // Also a clear fibre entered at |h| = 1 (a direction almost in the normal plane, h from it).
    const Vec3 edges[] = {Vec3(1, 0, 0),           Vec3(-1, 0, 0),
                          Vec3(0, 0, 1),           Vec3(0, 1, 0),
                          Vec3(0, 0, -1),          direction(0.999999f, 1.0f),
                          Vec3(0.6f, 0.8f, 1e-6f), Vec3(0.6f, -0.8f, -1e-6f)};
    for (const Rgb& sigma_a : {p.sigma_a, Rgb(0.0f)}) {
        p.sigma_a = sigma_a;
        for (const HairBsdf& hair :
             {HairBsdf(p, 0.3f), HairBsdf(p, 1.0f), HairBsdf(p, HairOffset::FromDirection)})
            for (const Vec3& wo : edges)
                for (const Vec3& wi : edges)
                    for (TransportMode mode :
                         {TransportMode::Radiance, TransportMode::Importance}) {
                        ASSERT_TRUE(hair.f(wo, wi, mode).is_finite()) << wo << wi;
                        ASSERT_TRUE(std::isfinite(hair.pdf_w(wo, wi).forward)) << wo << wi;
                    }
    }
}

// Importance mode is the adjoint: f(wo, wi, Importance) = f(wi, wo, Radiance).
TEST(Hair, ImportanceModeIsTheAdjoint) {
    HairParams p;
    p.sigma_a = Rgb(0.3f, 0.7f, 1.2f);
    Rng rng(StreamKey{34, 0, 6, 0});
    for (int i = 0; i < 20000; ++i) {
        const float h = -1 + 2 * rng.next_1d();
        const HairBsdf hair = i % 2 ? HairBsdf(p, h) : HairBsdf(p, HairOffset::FromDirection);
        const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
        const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
        const Rgb a = hair.f(wo, wi, TransportMode::Importance);
        const Rgb b = hair.f(wi, wo, TransportMode::Radiance);
        for (int c = 0; c < 3; ++c) ASSERT_EQ(a[c], b[c]) << wo << wi;
    }
}

// Where the model is reciprocal, S = f |cos theta_i| is symmetric; where it is not (h != 0),
// it measurably differs (so the check above is not vacuous).
TEST(Hair, ScatteringIsReciprocalAtTheCentreWithoutTilt) {
    HairParams p;
    p.sigma_a = Rgb(0.3f, 0.7f, 1.2f);
    p.alpha = 0;
    Rng rng(StreamKey{34, 0, 7, 0});
    const HairBsdf centre(p, 0.0f), off_centre(p, 0.6f);
    int asymmetric = 0;
    for (int i = 0; i < 20000; ++i) {
        const float sin_theta = -1 + 2 * rng.next_1d();
        const float sign = rng.next_1d() < 0.5f ? -1.0f : 1.0f;
        const Vec3 wo = direction(sin_theta, (2 * kPi) * rng.next_1d());
        const Vec3 wi = direction(sign * sin_theta, (2 * kPi) * rng.next_1d());
        const Rgb a = centre.f_cos(wo, wi), b = centre.f_cos(wi, wo);
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(close(a[c], b[c], 2e-4f)) << wo << wi;
        const Rgb x = off_centre.f_cos(wo, wi), y = off_centre.f_cos(wi, wo);
        asymmetric += !close(x.average(), y.average(), 1e-2f);
    }
    EXPECT_GT(asymmetric, 5000);
}

// The chi-square checks of this file, Sidak-corrected together.
ChiSquareFamily family;

struct HairCase {
    std::string name;
    HairParams params;
    float h;  // NaN: h from the direction (Mitsuba's)
    Vec3 wo;
};

void PrintTo(const HairCase& c, std::ostream* os) {
    *os << c.name;
}

std::vector<HairCase> chi_square_cases() {
    HairParams brown;
    brown.sigma_a = HairBsdf::sigma_a_from_concentration(1.3f, 0.0f);
    HairParams blond = brown;
    blond.sigma_a = HairBsdf::sigma_a_from_concentration(0.3f, 0.2f);
    blond.beta_m = 0.25f;
    blond.beta_n = 0.4f;
    HairParams rough = white(0.8f, 0.9f, 5.0f);
    HairParams white_smooth = white(0.2f, 0.2f, 2.0f);
    return {
        {"brown_centre", brown, 0.0f, direction(0.3f, 0.9f)},
        {"brown_edge", brown, 0.9f, direction(-0.5f, 2.0f)},
        {"blond_grazing_fibre", blond, -0.4f, direction(0.85f, -1.2f)},
        {"rough_white", rough, 0.2f, direction(0.1f, 0.3f)},
        {"white_smooth", white_smooth, -0.7f, direction(-0.2f, 1.4f)},
        {"brown_h_from_direction", brown, std::nanf(""), direction(0.4f, 2.6f)},
    };
}

const ChiSquareDeclaration kHairChecks(family, "HairChiSquare.SamplesFollowPdf", 1,
                                       int(chi_square_cases().size()));

class HairChiSquare : public ::testing::TestWithParam<HairCase> {};

TEST_P(HairChiSquare, SamplesFollowPdf) {
    const HairCase& c = GetParam();
    const HairBsdf hair =
        std::isnan(c.h) ? HairBsdf(c.params, HairOffset::FromDirection) : HairBsdf(c.params, c.h);
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        const float u_lobe = rng.next_1d();
        const auto s = hair.sample(c.wo, u_lobe, rng.next_2d(), TransportMode::Radiance);
        if (!s) return std::nullopt;
        return s->wi;
    };
    auto pdf = [&](const Vec3& wi) { return double(hair.pdf_w(c.wo, wi).forward); };
    ChiSquareOptions options;
    options.resolution_x = 128;
    options.resolution_y = 64;
    options.sample_count = 500000;
    options.seed = std::hash<std::string>()(c.name);
    const ChiSquareResult result = chi_square_test_sphere(family, sample, pdf, options);
    EXPECT_TRUE(result.passed) << hair.to_string() << ": " << result.message;
    // Every sample is a direction: the density integrates to one.
    EXPECT_NEAR(result.pdf_integral, 1.0, 3e-3) << result.message;
}

INSTANTIATE_TEST_SUITE_P(Fibres, HairChiSquare, ::testing::ValuesIn(chi_square_cases()),
                         [](const auto& info) { return info.param.name; });

Properties hair_props() {
    return Properties("bsdf", "hair", SourceLocation{"hair_test", 1});
}

// pbrt-v4's material resolves h = -1 + 2 v at every hit.
TEST(HairMaterial, PbrtMaterialResolvesHFromTheHitsV) {
    HairParams params;
    params.sigma_a = HairBsdf::sigma_a_from_concentration(1.3f, 0);
    const std::shared_ptr<const Bsdf> material = HairBsdf::pbrt_material(params);
    ASSERT_TRUE(material->varies());
    const auto at = std::dynamic_pointer_cast<const HairBsdf>(material->at(Vec2(0.3f, 0.75f)));
    ASSERT_TRUE(at);
    EXPECT_EQ(at->offset(), HairOffset::FromHitV);
    EXPECT_FLOAT_EQ(at->h(), 0.5f);
    EXPECT_EQ(at->to_string(), HairBsdf(params, 0.5f).to_string());
}

// Mitsuba 3's plugin: its names and defaults, h from the camera-side direction: the sine of the
// azimuthal angle between it and the normal, -w.y / |(w.y, w.z)|; such a BSDF equals the
// FromHitV one at that h.
TEST(HairMaterial, MitsubaPluginTakesHFromTheDirection) {
    Properties props = hair_props();
    const std::shared_ptr<const Bsdf> material = make_bsdf(props);
    props.check_all_used();
    EXPECT_FALSE(material->varies());
    const auto* hair = dynamic_cast<const HairBsdf*>(material.get());
    ASSERT_TRUE(hair);
    EXPECT_EQ(hair->offset(), HairOffset::FromDirection);
    HairParams expected;
    expected.sigma_a = HairBsdf::sigma_a_from_concentration(1.3f, 0.2f);
    expected.eta = 1.55f / 1.000277f;
    EXPECT_EQ(hair->to_string(), HairBsdf(expected, HairOffset::FromDirection).to_string());
    Rng rng(StreamKey{34, 0, 8, 0});
    for (int i = 0; i < 2000; ++i) {
        const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
        const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
        const float h = -wo.y / std::sqrt(wo.y * wo.y + wo.z * wo.z);
        ASSERT_NEAR(hair->h_for(wo), h, 1e-6f);
        const HairBsdf at_h(expected, h);
        const Rgb a = hair->f(wo, wi, TransportMode::Radiance);
        const Rgb b = at_h.f(wo, wi, TransportMode::Radiance);
        for (int c = 0; c < 3; ++c) ASSERT_TRUE(close(a[c], b[c], 1e-5f)) << wo << wi;
        ASSERT_TRUE(close(hair->pdf_w(wo, wi).forward, at_h.pdf_w(wo, wi).forward, 1e-5f));
    }
}

TEST(HairMaterial, ParametersAndConversions) {
    // Melanin: pbrt-v4's absorption coefficients per unit concentration.
    const Rgb s = HairBsdf::sigma_a_from_concentration(2.0f, 1.0f);
    EXPECT_NEAR(s.r, 2 * 0.419f + 0.187f, 1e-6f);
    EXPECT_NEAR(s.b, 2 * 1.37f + 1.05f, 1e-6f);
    // Reflectance: a white fibre absorbs nothing; darker ones absorb more.
    const Rgb none = HairBsdf::sigma_a_from_reflectance(Rgb(1.0f), 0.3f);
    EXPECT_EQ(none, Rgb(0.0f));
    const Rgb dark = HairBsdf::sigma_a_from_reflectance(Rgb(0.1f, 0.3f, 0.6f), 0.3f);
    EXPECT_GT(dark.r, dark.g);
    EXPECT_GT(dark.g, dark.b);
    EXPECT_GT(dark.b, 0.0f);
    // Both colour specifications at once, and out-of-range roughness, are errors.
    const SourceLocation at{"hair_test", 2};
    Properties both = hair_props();
    both.set("sigma_a", Rgb(0.5f), at);
    both.set("eumelanin", 0.5f, at);
    EXPECT_THROW(make_bsdf(both), SceneError);
    Properties beta = hair_props();
    beta.set("longitudinal_roughness", 1.5f, at);
    EXPECT_THROW(make_bsdf(beta), SceneError);
    Properties same = hair_props();
    same.set("int_ior", 1.0f, at);
    same.set("ext_ior", 1.0f, at);
    EXPECT_THROW(make_bsdf(same), SceneError);
    Properties full = hair_props();
    full.set("sigma_a", Rgb(0.3f, 0.2f, 0.1f), at);
    full.set("scale", 2.0f, at);
    full.set("int_ior", 1.6f, at);
    full.set("azimuthal_roughness", 0.5f, at);
    full.set("scale_tilt", 3.0f, at);
    const auto built = make_bsdf(full);
    full.check_all_used();
    HairParams expected;
    expected.sigma_a = Rgb(0.6f, 0.4f, 0.2f);
    expected.eta = 1.6f / 1.000277f;
    expected.beta_n = 0.5f;
    expected.alpha = 3;
    EXPECT_EQ(built->to_string(), HairBsdf(expected, HairOffset::FromDirection).to_string());
}

}  // namespace
}  // namespace render
