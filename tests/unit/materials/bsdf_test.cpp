// Deterministic and Monte Carlo checks of the BSDF models: sample/pdf/f consistency, both
// directional densities, reciprocity, energy conservation, known closed-form values, and the
// factory's parameter handling. The sampling distributions themselves are checked by the
// chi-square tests in bsdf_chi_square_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/materials/blend.h"
#include "core/materials/bsdf_factory.h"
#include "core/materials/conductor.h"
#include "core/materials/dielectric.h"
#include "core/materials/diffuse.h"
#include "core/materials/diffuse_transmission.h"
#include "core/materials/fresnel.h"
#include "core/materials/ior.h"
#include "core/materials/microfacet.h"
#include "core/materials/null_bsdf.h"
#include "core/materials/phong.h"
#include "core/materials/plastic.h"
#include "core/materials/rough_conductor.h"
#include "core/materials/rough_dielectric.h"
#include "core/materials/rough_plastic.h"
#include "core/materials/thin_dielectric.h"
#include "core/materials/twosided.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

constexpr TransportMode kRadiance = TransportMode::Radiance;
constexpr TransportMode kImportance = TransportMode::Importance;

Vec3 direction(float cos_theta, float phi = 0.7f) {
    const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
    return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

// |a - b| <= rel * max(|a|, |b|) + abs.
::testing::AssertionResult close(double a, double b, double rel, double abs = 0) {
    if (std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + abs)
        return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << a << " vs " << b << " (difference " << a - b << ")";
}
::testing::AssertionResult close(const Rgb& a, const Rgb& b, double rel, double abs = 0) {
    for (int c = 0; c < 3; ++c)
        if (!close(a[c], b[c], rel, abs))
            return close(a[c], b[c], rel, abs) << " in " << a << " vs " << b;
    return ::testing::AssertionSuccess();
}

struct NamedBsdf {
    std::string name;
    std::shared_ptr<const Bsdf> bsdf;
    bool transmissive = false;
};

const ConductorIor kCopper{Rgb(0.200438f, 0.924033f, 1.10221f), Rgb(3.91295f, 2.45285f, 2.14219f)};

std::vector<NamedBsdf> all_bsdfs() {
    auto rough_conductor = [](MicrofacetType type, float au, float av, bool visible) {
        return std::make_shared<RoughConductorBsdf>(MicrofacetDistribution(type, au, av, visible),
                                                    kCopper, Rgb(0.9f));
    };
    auto rough_dielectric = [](MicrofacetType type, float alpha, bool visible) {
        return std::make_shared<RoughDielectricBsdf>(
            MicrofacetDistribution(type, alpha, alpha, visible), 1.5f, Rgb(1.0f), Rgb(1.0f));
    };
    auto rough_plastic = [](MicrofacetType type, float alpha, const Rgb& kd, const Rgb& ks,
                            bool nonlinear) {
        auto coating =
            std::make_shared<RoughCoating>(MicrofacetDistribution(type, alpha, alpha), 1.49f);
        return std::make_shared<RoughPlasticBsdf>(coating, kd, ks, nonlinear);
    };
    auto diffuse = std::make_shared<DiffuseBsdf>(Rgb(0.2f, 0.5f, 0.8f));
    auto phong = std::make_shared<PhongBsdf>(Rgb(0.1f), Rgb(0.7f), 90.0f);
    return {
        {"diffuse", diffuse},
        {"twosided_diffuse", std::make_shared<TwoSidedBsdf>(diffuse, nullptr)},
        {"twosided_front_back", std::make_shared<TwoSidedBsdf>(diffuse, phong)},
        {"conductor_none", std::make_shared<ConductorBsdf>(std::nullopt, Rgb(1.0f))},
        {"conductor_copper", std::make_shared<ConductorBsdf>(kCopper, Rgb(1.0f))},
        {"roughconductor_beckmann", rough_conductor(MicrofacetType::Beckmann, 0.3f, 0.3f, true)},
        {"roughconductor_ggx", rough_conductor(MicrofacetType::GGX, 0.3f, 0.3f, true)},
        {"roughconductor_beckmann_aniso",
         rough_conductor(MicrofacetType::Beckmann, 0.05f, 0.6f, true)},
        {"roughconductor_ggx_all_normals", rough_conductor(MicrofacetType::GGX, 0.4f, 0.2f, false)},
        {"roughconductor_tiny_alpha", rough_conductor(MicrofacetType::GGX, 0.0f, 0.0f, true)},
        {"dielectric", std::make_shared<DielectricBsdf>(1.5f, Rgb(1.0f), Rgb(1.0f)), true},
        {"thindielectric", std::make_shared<ThinDielectricBsdf>(1.5f, Rgb(1.0f), Rgb(1.0f)), true},
        {"thindielectric_tinted",
         std::make_shared<ThinDielectricBsdf>(1.33f, Rgb(0.9f, 0.8f, 0.7f), Rgb(0.5f, 0.6f, 0.7f)),
         true},
        {"roughdielectric_ggx", rough_dielectric(MicrofacetType::GGX, 0.3f, true), true},
        {"roughdielectric_beckmann", rough_dielectric(MicrofacetType::Beckmann, 0.5f, true), true},
        {"roughdielectric_ggx_all_normals", rough_dielectric(MicrofacetType::GGX, 0.2f, false),
         true},
        {"plastic", std::make_shared<PlasticBsdf>(Rgb(0.5f), Rgb(1.0f), 1.49f, false)},
        {"plastic_nonlinear",
         std::make_shared<PlasticBsdf>(Rgb(0.9f, 0.5f, 0.1f), Rgb(0.4f), 1.7f, true)},
        {"roughplastic_beckmann",
         rough_plastic(MicrofacetType::Beckmann, 0.1f, Rgb(0.5f), Rgb(1.0f), false)},
        {"roughplastic_ggx_nonlinear",
         rough_plastic(MicrofacetType::GGX, 0.4f, Rgb(0.9f, 0.5f, 0.1f), Rgb(0.4f), true)},
        {"roughplastic_white_smooth",
         rough_plastic(MicrofacetType::GGX, 0.01f, Rgb(1.0f), Rgb(1.0f), false)},
        {"blend_diffuse_roughconductor",
         std::make_shared<BlendBsdf>(diffuse,
                                     rough_conductor(MicrofacetType::GGX, 0.2f, 0.2f, true), 0.3f)},
        {"blend_mirror_diffuse",
         std::make_shared<BlendBsdf>(std::make_shared<ConductorBsdf>(std::nullopt, Rgb(1.0f)),
                                     diffuse, 0.6f)},
        {"blend_roughplastic_roughdielectric",
         std::make_shared<BlendBsdf>(
             rough_plastic(MicrofacetType::Beckmann, 0.2f, Rgb(0.5f), Rgb(1.0f), false),
             rough_dielectric(MicrofacetType::GGX, 0.3f, true), 0.4f),
         true},
        {"mask_diffuse",
         std::make_shared<BlendBsdf>(std::make_shared<NullBsdf>(), diffuse, 0.35f, true)},
        {"phong_cornell_floor", phong},
        {"phong_n1", std::make_shared<PhongBsdf>(Rgb(0.3f), Rgb(0.6f), 1.0f)},
        // Transmits, but symmetric in wo and wi and without an index: the reciprocity of
        // reflection holds for both its lobes (not `transmissive`, which means a dielectric).
        {"diffusetransmission",
         std::make_shared<DiffuseTransmissionBsdf>(Rgb(0.2f, 0.5f, 0.8f), Rgb(0.6f, 0.3f, 0.1f))},
        {"diffusetransmission_transmit_only",
         std::make_shared<DiffuseTransmissionBsdf>(Rgb(0.0f), Rgb(0.9f, 0.7f, 0.5f))},
    };
}

// Directions that exercise the edge cases as well as the bulk.
std::vector<Vec3> test_directions(Rng& rng, int random_count) {
    std::vector<Vec3> dirs = {Vec3(0, 0, 1),         Vec3(0, 0, -1),        Vec3(1, 0, 0),
                              direction(1e-6f),      direction(-1e-6f),     direction(1e-3f, 2.0f),
                              direction(0.9999999f), direction(-0.5f, 4.0f)};
    for (int i = 0; i < random_count; ++i)
        dirs.push_back(warp::square_to_uniform_sphere(rng.next_2d()));
    return dirs;
}

TEST(Bsdf, SampleAgreesWithEvalAndPdf) {
    for (const NamedBsdf& entry : all_bsdfs()) {
        SCOPED_TRACE(entry.name);
        const Bsdf& bsdf = *entry.bsdf;
        Rng rng(StreamKey{7, 0, 1, 0});
        int checked = 0;
        for (const Vec3& wo : test_directions(rng, 1000))
            for (TransportMode mode : {kRadiance, kImportance})
                for (int k = 0; k < 4; ++k) {
                    const float u_lobe = rng.next_1d();
                    std::optional<BsdfSample> s = bsdf.sample(wo, u_lobe, rng.next_2d(), mode);
                    if (!s) continue;
                    ASSERT_TRUE(is_finite(s->wi)) << wo;
                    ASSERT_NEAR(length(s->wi), 1.0f, 1e-4f) << wo;
                    ASSERT_TRUE(s->weight.is_finite()) << wo;
                    ASSERT_GE(std::min(s->weight.r, std::min(s->weight.g, s->weight.b)), 0.0f);
                    ASSERT_TRUE(std::isfinite(s->eta) && s->eta > 0);
                    if (s->delta) {
                        EXPECT_TRUE(s->lobe & kLobeDelta);
                        EXPECT_GT(s->pdf_w.forward, 0.0f);
                        EXPECT_LE(s->pdf_w.forward, 1.0f);
                        EXPECT_GT(s->pdf_w.reverse, 0.0f);
                        EXPECT_LE(s->pdf_w.reverse, 1.0f);
                        continue;
                    }
                    EXPECT_TRUE(s->lobe & kLobeNonDelta);
                    const BsdfPdf pdf_w = bsdf.pdf_w(wo, s->wi);
                    EXPECT_TRUE(close(pdf_w.forward, s->pdf_w.forward, 1e-4)) << wo << " " << s->wi;
                    EXPECT_TRUE(close(pdf_w.reverse, s->pdf_w.reverse, 1e-4)) << wo << " " << s->wi;
                    EXPECT_TRUE(close(bsdf.pdf_w(s->wi, wo).forward, s->pdf_w.reverse, 1e-4))
                        << wo << " " << s->wi;
                    const Rgb expected =
                        bsdf.f(wo, s->wi, mode) * (std::abs(s->wi.z) / pdf_w.forward);
                    EXPECT_TRUE(close(expected, s->weight, 1e-4, 1e-7)) << wo << " " << s->wi;
                    ++checked;
                }
        if (entry.bsdf->has_non_delta()) {
            EXPECT_GT(checked, 1000);
        }
    }
}

TEST(Bsdf, EvalAndPdfAreFiniteAndReverseIsSwappedForward) {
    for (const NamedBsdf& entry : all_bsdfs()) {
        SCOPED_TRACE(entry.name);
        const Bsdf& bsdf = *entry.bsdf;
        Rng rng(StreamKey{8, 0, 1, 0});
        const std::vector<Vec3> dirs = test_directions(rng, 150);
        for (const Vec3& wo : dirs)
            for (const Vec3& wi : dirs) {
                const BsdfPdf pdf_w = bsdf.pdf_w(wo, wi);
                ASSERT_TRUE(std::isfinite(pdf_w.forward) && pdf_w.forward >= 0) << wo << wi;
                ASSERT_TRUE(std::isfinite(pdf_w.reverse) && pdf_w.reverse >= 0) << wo << wi;
                EXPECT_EQ(pdf_w.reverse, bsdf.pdf_w(wi, wo).forward) << wo << wi;
                for (TransportMode mode : {kRadiance, kImportance}) {
                    const Rgb f = bsdf.f(wo, wi, mode);
                    ASSERT_TRUE(f.is_finite()) << wo << wi;
                    ASSERT_GE(std::min(f.r, std::min(f.g, f.b)), 0.0f) << wo << wi;
                    // A value with zero density could never be sampled.
                    if (!f.is_black()) {
                        EXPECT_GT(pdf_w.forward, 0.0f) << wo << wi;
                    }
                }
            }
        // Delta BSDFs report nothing to evaluation.
        if (bsdf.is_delta()) {
            EXPECT_TRUE(bsdf.f(dirs[0], reflect_z(dirs[0]), kRadiance).is_black());
            EXPECT_EQ(bsdf.pdf_w(dirs[0], reflect_z(dirs[0])).forward, 0.0f);
        }
    }
}

// evaluate() is f() and pdf_w() in one call: an override (Phong's shares one power of the lobe
// cosine) must return exactly their values, bit for bit, or images would change with the caller.
TEST(Bsdf, EvaluateIsFAndPdfBitForBit) {
    auto same_bits = [](float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; };
    for (const NamedBsdf& entry : all_bsdfs()) {
        SCOPED_TRACE(entry.name);
        const Bsdf& bsdf = *entry.bsdf;
        Rng rng(StreamKey{9, 0, 1, 0});
        std::vector<Vec3> dirs = test_directions(rng, 120);
        // Pairs near the Phong lobe's peak, where its power matters most.
        for (int i = 0; i < 40; ++i) {
            const Vec3 wo = warp::square_to_cosine_hemisphere(rng.next_2d());
            dirs.push_back(normalize(reflect_z(wo) + warp::square_to_uniform_sphere(rng.next_2d()) *
                                                         (0.01f * rng.next_1d())));
        }
        int nonzero = 0;
        for (const Vec3& wo : dirs)
            for (const Vec3& wi : dirs)
                for (TransportMode mode : {kRadiance, kImportance}) {
                    const BsdfEvaluation e = bsdf.evaluate(wo, wi, mode);
                    const Rgb f = bsdf.f(wo, wi, mode);
                    const BsdfPdf pdf_w = bsdf.pdf_w(wo, wi);
                    for (int c = 0; c < 3; ++c)
                        ASSERT_TRUE(same_bits(e.f[c], f[c])) << wo << wi << " " << e.f << f;
                    ASSERT_TRUE(same_bits(e.pdf_w.forward, pdf_w.forward)) << wo << wi;
                    ASSERT_TRUE(same_bits(e.pdf_w.reverse, pdf_w.reverse)) << wo << wi;
                    nonzero += !f.is_black();
                }
        if (bsdf.has_non_delta()) {
            EXPECT_GT(nonzero, 1000);
        }
    }
}

TEST(Bsdf, ReflectionIsReciprocal) {
    for (const NamedBsdf& entry : all_bsdfs()) {
        if (entry.transmissive || entry.bsdf->is_delta()) continue;
        SCOPED_TRACE(entry.name);
        Rng rng(StreamKey{9, 0, 1, 0});
        for (int i = 0; i < 20000; ++i) {
            const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
            const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
            for (TransportMode mode : {kRadiance, kImportance})
                ASSERT_TRUE(
                    close(entry.bsdf->f(wo, wi, mode), entry.bsdf->f(wi, wo, mode), 1e-4, 1e-6))
                    << wo << " " << wi;
        }
    }
}

TEST(Bsdf, RoughDielectricTransmissionIsAdjointAndGeneralisedReciprocal) {
    for (const NamedBsdf& entry : all_bsdfs()) {
        if (!entry.transmissive || entry.bsdf->is_delta()) continue;
        SCOPED_TRACE(entry.name);
        const Bsdf& bsdf = *entry.bsdf;
        Rng rng(StreamKey{10, 0, 1, 0});
        int transmissions = 0;
        for (int i = 0; i < 20000; ++i) {
            const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
            const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
            // Skip pairs that graze their micro-facet: there 1 - F is a difference of nearly
            // equal numbers (the critical angle on the inside), and float rounding of the two
            // evaluation orders differs by ~1e-3 relative.
            const float etap_pair = wo.z * wi.z > 0 ? 1.0f : (wo.z > 0 ? 1.5f : 1.0f / 1.5f);
            const Vec3 m = normalize(wi * etap_pair + wo);
            if (std::abs(dot(wo, m)) < 0.05f || std::abs(dot(wi, m)) < 0.05f) continue;
            // The adjoint BSDF is the BSDF with its arguments swapped (Veach, section 5.2):
            // importance flows wo -> wi as radiance flows wi -> wo.
            ASSERT_TRUE(close(bsdf.f(wo, wi, kImportance), bsdf.f(wi, wo, kRadiance), 2e-4, 1e-6))
                << wo << " " << wi;
            if (wo.z * wi.z >= 0) continue;
            // Radiance BTDF: f(wi, wo) = (n_i / n_o)^2 f(wo, wi), n_x = IOR on the side of x.
            const float etap = wo.z > 0 ? 1.5f : 1.0f / 1.5f;  // n(wi side) / n(wo side)
            const Rgb f_forward = bsdf.f(wo, wi, kRadiance);
            ASSERT_TRUE(close(bsdf.f(wi, wo, kRadiance), f_forward * (etap * etap), 2e-4, 1e-6))
                << wo << " " << wi;
            transmissions += !f_forward.is_black();
        }
        EXPECT_GT(transmissions, 1000);
    }
}

// Monte Carlo estimate of the directional albedo E[weight] with its standard error per channel.
struct Albedo {
    Rgb mean, standard_error;
};
Albedo estimate_albedo(const Bsdf& bsdf, const Vec3& wo, TransportMode mode, int n, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    testing::MeanAccumulator estimate[3];
    for (int i = 0; i < n; ++i) {
        const float u_lobe = rng.next_1d();
        std::optional<BsdfSample> s = bsdf.sample(wo, u_lobe, rng.next_2d(), mode);
        for (int c = 0; c < 3; ++c) estimate[c].add(s ? s->weight[c] : 0.0);  // failed: 0
    }
    Albedo albedo;
    for (int c = 0; c < 3; ++c) {
        albedo.mean[c] = float(estimate[c].mean());
        albedo.standard_error[c] = float(estimate[c].standard_error());
    }
    return albedo;
}

TEST(Bsdf, ConservesEnergy) {
    // E[weight] is the directional albedo; it may not exceed 1. The estimate may exceed 1 by
    // chance, so the bound is 1 + 4 standard errors (a false alarm has probability ~3e-5 per
    // check), plus 1e-5 for float rounding of deterministic weights. Transmissive BSDFs are
    // checked in Importance mode: their Radiance-mode weights carry the 1/eta^2 solid-angle
    // compression, which is not an energy gain.
    constexpr int n = 100000;
    for (const NamedBsdf& entry : all_bsdfs()) {
        SCOPED_TRACE(entry.name);
        const TransportMode mode = entry.transmissive ? kImportance : kRadiance;
        for (float c : {0.999f, 0.9f, 0.5f, 0.1f, 0.01f, -0.3f, -0.9f}) {
            const Albedo albedo =
                estimate_albedo(*entry.bsdf, direction(c), mode, n, uint64_t(1000 * (c + 2)));
            for (int k = 0; k < 3; ++k)
                EXPECT_LE(albedo.mean[k], 1.0f + 4.0f * albedo.standard_error[k] + 1e-5f)
                    << "cos " << c << ", channel " << k;
        }
    }
}

TEST(Bsdf, SmoothDielectricWhiteFurnace) {
    // Lossless interface: every sample carries weight 1 in Importance mode, so reflection plus
    // transmission is exactly 1; the reflected fraction is the Fresnel reflectance.
    const DielectricBsdf glass(1.6f, Rgb(1.0f), Rgb(1.0f));
    for (float c : {0.95f, 0.6f, 0.2f, -0.95f, -0.8f, -0.6f}) {
        SCOPED_TRACE(c);
        const Vec3 wo = direction(c);
        const Albedo albedo = estimate_albedo(glass, wo, kImportance, 20000, 3);
        EXPECT_TRUE(close(albedo.mean, Rgb(1.0f), 1e-6));
        const float R = fresnel_dielectric(c, 1.6f).reflectance;
        Rng rng(StreamKey{4, 0, 1, 0});
        int reflected = 0;
        constexpr int n = 20000;
        for (int i = 0; i < n; ++i) {
            const float u_lobe = rng.next_1d();
            reflected += glass.sample(wo, u_lobe, rng.next_2d(), kImportance)->wi.z * c > 0;
        }
        EXPECT_NEAR(double(reflected) / n, R, 4.0 * std::sqrt(R * (1 - R) / n) + 1e-6);
        // Radiance mode: transmitted radiance is scaled by (n_o / n_i)^2.
        const float eta_ti = c > 0 ? 1.0f / 1.6f : 1.6f;
        const Albedo radiance = estimate_albedo(glass, wo, kRadiance, 200000, 5);
        const float expected = R + (1 - R) * eta_ti * eta_ti;
        EXPECT_NEAR(radiance.mean.r, expected, 4.0f * radiance.standard_error.r + 1e-5f);
    }
}

TEST(Bsdf, ThinDielectricSlabFresnelAndStraightTransmission) {
    // Lossless slab: weight 1 in both modes (no refraction, so no radiance scaling); the
    // reflected fraction is R' = R + T^2 R / (1 - R^2) of the single interface's R, which for
    // a lossless slab is 2R / (1 + R).
    const ThinDielectricBsdf pane(1.5f, Rgb(1.0f), Rgb(1.0f));
    for (float c : {0.95f, 0.6f, 0.2f, 0.02f, -0.95f, -0.5f, -0.1f}) {
        SCOPED_TRACE(c);
        const Vec3 wo = direction(c, 0.4f);
        const float R = fresnel_dielectric(std::abs(c), 1.5f).reflectance;
        const float slab = R + (1 - R) * (1 - R) * R / (1 - R * R);
        EXPECT_NEAR(pane.slab_reflectance(c), slab, 1e-6f);
        EXPECT_NEAR(pane.slab_reflectance(c), 2 * R / (1 + R), 1e-6f);
        EXPECT_EQ(pane.slab_reflectance(c), pane.slab_reflectance(-c));  // both sides alike
        for (TransportMode mode : {kRadiance, kImportance})
            EXPECT_TRUE(close(estimate_albedo(pane, wo, mode, 20000, 3).mean, Rgb(1.0f), 1e-6));
        // Deterministic lobe choice: u_lobe below R' reflects, above transmits straight on.
        std::optional<BsdfSample> r = pane.sample(wo, 0.5f * slab, Vec2(0.3f, 0.3f), kRadiance);
        ASSERT_TRUE(r);
        EXPECT_EQ(r->lobe, kLobeDeltaReflection);
        EXPECT_EQ(r->wi, reflect_z(wo));
        EXPECT_NEAR(r->pdf_w.forward, slab, 1e-6f);
        std::optional<BsdfSample> t =
            pane.sample(wo, 0.5f * (1 + slab), Vec2(0.3f, 0.3f), kImportance);
        ASSERT_TRUE(t);
        EXPECT_EQ(t->lobe, kLobeDeltaTransmission);
        EXPECT_EQ(t->wi, -wo);
        EXPECT_EQ(t->eta, 1.0f);
        EXPECT_NEAR(t->pdf_w.forward, 1 - slab, 1e-6f);
        // Reciprocity: the reverse density is the forward density of the reverse sample.
        EXPECT_EQ(t->pdf_w.reverse, 1.0f - pane.slab_reflectance(t->wi.z));
        EXPECT_EQ(r->pdf_w.reverse, pane.slab_reflectance(r->wi.z));
    }
    // Tints scale the two lobes; a slab of index 1 transmits everything.
    const ThinDielectricBsdf tinted(1.5f, Rgb(0.5f), Rgb(0.25f));
    const float R = tinted.slab_reflectance(0.8f);
    const Albedo albedo = estimate_albedo(tinted, direction(0.8f), kRadiance, 200000, 9);
    EXPECT_NEAR(albedo.mean.r, 0.5f * R + 0.25f * (1 - R), 4 * albedo.standard_error.r + 1e-6f);
    EXPECT_EQ(ThinDielectricBsdf(1.0f, Rgb(1.0f), Rgb(1.0f)).slab_reflectance(0.3f), 0.0f);
    // From the denser side (eta < 1) beyond the critical angle, nothing enters the slab.
    EXPECT_EQ(ThinDielectricBsdf(1.0f / 1.5f, Rgb(1.0f), Rgb(1.0f)).slab_reflectance(0.2f), 1.0f);
}

TEST(Bsdf, DiffuseAlbedoIsReflectance) {
    const Rgb reflectance(0.2f, 0.5f, 0.8f);
    const DiffuseBsdf diffuse(reflectance);
    Rng rng(StreamKey{11, 0, 1, 0});
    for (int i = 0; i < 10000; ++i) {
        const Vec3 wo = direction(rng.next_1d() * 0.999f + 0.001f, 6.28f * rng.next_1d());
        std::optional<BsdfSample> s = diffuse.sample(wo, rng.next_1d(), rng.next_2d(), kRadiance);
        ASSERT_TRUE(s);
        EXPECT_EQ(s->weight, reflectance);
        EXPECT_GT(s->wi.z, 0.0f);
        EXPECT_EQ(s->lobe, kLobeDiffuseReflection);
    }
    // One-sided.
    EXPECT_FALSE(diffuse.sample(direction(-0.5f), 0.5f, Vec2(0.3f, 0.3f), kRadiance));
    EXPECT_TRUE(diffuse.f(direction(-0.5f), direction(0.5f), kRadiance).is_black());
    EXPECT_TRUE(close(diffuse.f(direction(0.5f), direction(0.3f), kRadiance),
                      reflectance * (1.0f / kPi), 1e-6));
}

TEST(Bsdf, TwoSidedMirrorsTheBackSide) {
    const Rgb reflectance(0.2f, 0.5f, 0.8f);
    auto diffuse = std::make_shared<DiffuseBsdf>(reflectance);
    auto back = std::make_shared<DiffuseBsdf>(Rgb(0.1f));
    const TwoSidedBsdf one(diffuse, nullptr), two(diffuse, back);
    const Vec3 wo = direction(-0.4f), wi = direction(-0.7f, 2.0f);
    EXPECT_EQ(one.f(wo, wi, kRadiance), reflectance * kInvPi);
    EXPECT_EQ(two.f(wo, wi, kRadiance), Rgb(0.1f) * kInvPi);
    EXPECT_EQ(two.f(-wo, -wi, kRadiance), reflectance * kInvPi);
    EXPECT_TRUE(one.f(wo, -wi, kRadiance).is_black());  // no transmission
    std::optional<BsdfSample> s = one.sample(wo, 0.5f, Vec2(0.2f, 0.6f), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_LT(s->wi.z, 0.0f);
    EXPECT_EQ(s->weight, reflectance);
    EXPECT_FALSE(one.sample(Vec3(1, 0, 0), 0.5f, Vec2(0.2f, 0.6f), kRadiance));
}

TEST(Bsdf, ConductorWithoutFresnelIsAPerfectMirror) {
    const ConductorBsdf mirror(std::nullopt, Rgb(1.0f));
    Rng rng(StreamKey{12, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        const Vec3 wo = direction(rng.next_1d() * 0.999f + 0.001f, 6.28f * rng.next_1d());
        for (TransportMode mode : {kRadiance, kImportance}) {
            std::optional<BsdfSample> s = mirror.sample(wo, rng.next_1d(), rng.next_2d(), mode);
            ASSERT_TRUE(s);
            EXPECT_EQ(s->weight, Rgb(1.0f));
            EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
            EXPECT_TRUE(s->delta);
            EXPECT_EQ(s->lobe, kLobeDeltaReflection);
            EXPECT_EQ(s->pdf_w.forward, 1.0f);
            EXPECT_EQ(s->pdf_w.reverse, 1.0f);
            EXPECT_TRUE(mirror.f(wo, s->wi, mode).is_black());
            EXPECT_EQ(mirror.pdf_w(wo, s->wi).forward, 0.0f);
        }
    }
    EXPECT_FALSE(mirror.sample(direction(-0.5f), 0.5f, Vec2(0.5f, 0.5f), kRadiance));
}

TEST(Bsdf, ConductorFresnelMatchesClosedForms) {
    // Normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2).
    const ConductorIor gold = *lookup_conductor_ior("Au");
    const Rgb normal = fresnel_conductor(1.0f, gold.eta, gold.k);
    for (int c = 0; c < 3; ++c) {
        const float n = gold.eta[c], k = gold.k[c];
        EXPECT_NEAR(normal[c], ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k), 1e-6);
    }
    // Gold is yellow: red reflects more than blue.
    EXPECT_GT(normal.r, normal.b + 0.3f);
    // With k = 0 the conductor formula is the dielectric one.
    for (float c : {1.0f, 0.8f, 0.5f, 0.2f, 0.05f})
        EXPECT_NEAR(fresnel_conductor(c, 1.5f, 0.0f), fresnel_dielectric(c, 1.5f).reflectance, 1e-5)
            << c;
    // Grazing incidence reflects everything.
    EXPECT_NEAR(fresnel_conductor(0.0f, 0.2f, 3.9f), 1.0f, 1e-6);
    // The smooth conductor applies it.
    const ConductorBsdf copper(kCopper, Rgb(0.5f));
    std::optional<BsdfSample> s = copper.sample(direction(0.6f), 0.5f, Vec2(), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_TRUE(close(s->weight, fresnel_conductor(0.6f, kCopper.eta, kCopper.k) * 0.5f, 1e-6));
}

TEST(Bsdf, DielectricFresnelAndRefraction) {
    // Normal incidence: ((n - 1) / (n + 1))^2 = 0.04 for n = 1.5, from either side.
    EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f).reflectance, 0.04f, 1e-6f);
    EXPECT_NEAR(fresnel_dielectric(-1.0f, 1.5f).reflectance, 0.04f, 1e-6f);
    const DielectricBsdf glass(1.5f, Rgb(1.0f), Rgb(1.0f));
    std::optional<BsdfSample> r = glass.sample(Vec3(0, 0, 1), 0.01f, Vec2(), kRadiance);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->lobe, kLobeDeltaReflection);
    EXPECT_NEAR(r->pdf_w.forward, 0.04f, 1e-6f);
    EXPECT_NEAR(r->pdf_w.reverse, 0.04f, 1e-6f);
    EXPECT_EQ(r->weight, Rgb(1.0f));
    EXPECT_EQ(r->wi, Vec3(0, 0, 1));

    std::optional<BsdfSample> t = glass.sample(Vec3(0, 0, 1), 0.5f, Vec2(), kRadiance);
    ASSERT_TRUE(t);
    EXPECT_EQ(t->lobe, kLobeDeltaTransmission);
    EXPECT_NEAR(t->pdf_w.forward, 0.96f, 1e-6f);
    EXPECT_NEAR(t->wi.z, -1.0f, 1e-6f);
    EXPECT_NEAR(t->eta, 1.5f, 1e-6f);
    EXPECT_TRUE(close(t->weight, Rgb(1.0f / 2.25f), 1e-6));
    t = glass.sample(Vec3(0, 0, 1), 0.5f, Vec2(), kImportance);
    EXPECT_TRUE(close(t->weight, Rgb(1.0f), 1e-6));
    t = glass.sample(Vec3(0, 0, -1), 0.5f, Vec2(), kRadiance);  // leaving the glass
    EXPECT_TRUE(close(t->weight, Rgb(2.25f), 1e-6));
    EXPECT_NEAR(t->eta, 1.0f / 1.5f, 1e-6f);

    // Snell's law at an oblique angle, and the reverse selection probability.
    const Vec3 wo = direction(0.6f, 1.0f);
    t = glass.sample(wo, 0.99f, Vec2(), kRadiance);
    ASSERT_TRUE(t && t->lobe == kLobeDeltaTransmission);
    EXPECT_NEAR(std::sqrt(1 - wo.z * wo.z), 1.5f * std::sqrt(1 - t->wi.z * t->wi.z), 1e-5f);
    EXPECT_NEAR(t->wi.x * wo.y - t->wi.y * wo.x, 0.0f, 1e-6f);  // same plane of incidence
    EXPECT_LT(t->wi.x * wo.x, 0.0f);                            // opposite side of the normal
    EXPECT_NEAR(t->pdf_w.reverse, t->pdf_w.forward, 1e-5f);     // Fresnel is symmetric

    // Total internal reflection beyond the critical angle (sin > 1 / 1.5) from inside.
    const Vec3 inside = direction(-0.5f);
    EXPECT_EQ(fresnel_dielectric(-0.5f, 1.5f).reflectance, 1.0f);
    for (float u : {0.0f, 0.5f, 0.999f}) {
        std::optional<BsdfSample> s = glass.sample(inside, u, Vec2(), kRadiance);
        ASSERT_TRUE(s);
        EXPECT_EQ(s->lobe, kLobeDeltaReflection);
        EXPECT_EQ(s->pdf_w.forward, 1.0f);
    }
    EXPECT_FALSE(glass.sample(Vec3(1, 0, 0), 0.5f, Vec2(), kRadiance));
}

TEST(Bsdf, DiffuseFresnelReflectance) {
    // Known value for n = 1.5 (e.g. d'Eon & Irving 2011) and the reciprocity identity between
    // the external and internal averages: 1 - Fdr(1/eta) = (1 - Fdr(eta)) / eta^2.
    EXPECT_NEAR(fresnel_diffuse_reflectance(1.5f), 0.0918f, 5e-4f);
    for (float eta : {1.1f, 1.33f, 1.5f, 2.4f})
        EXPECT_NEAR(1 - fresnel_diffuse_reflectance(1 / eta),
                    (1 - fresnel_diffuse_reflectance(eta)) / (eta * eta), 1e-4f)
            << eta;
    EXPECT_EQ(fresnel_diffuse_reflectance(1.0f), 0.0f);
}

TEST(Bsdf, WhitePlasticConservesEnergyExactly) {
    // With kd = ks = 1 (linear mode) nothing is absorbed: the specular part reflects F, the
    // rest enters, and the closed-form sum of internal bounces lets all of it out again.
    const PlasticBsdf white(Rgb(1.0f), Rgb(1.0f), 1.5f, false);
    for (float c : {0.95f, 0.5f, 0.1f}) {
        const Albedo albedo = estimate_albedo(white, direction(c), kRadiance, 400000, 21);
        EXPECT_NEAR(albedo.mean.g, 1.0f, 4.0f * albedo.standard_error.g + 1e-3f) << c;
    }
}

TEST(RoughPlastic, InterfaceAlbedosApproachTheSmoothFresnelTerms) {
    // A nearly smooth coating transmits 1 - F(cos) and reflects, hemispherically from inside,
    // the diffuse Fresnel reflectance Fdr(1 / eta) that `plastic` uses.
    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX}) {
        SCOPED_TRACE(to_string(type));
        const MicrofacetDistribution smooth(type, 1e-3f, 1e-3f);
        for (float c : {0.95f, 0.6f, 0.3f, 0.1f}) {
            EXPECT_NEAR(rough_interface_transmittance(smooth, c, 1.5f),
                        1 - fresnel_dielectric(c, 1.5f).reflectance, 2e-3)
                << c;
            // From inside (relative IOR 1/1.5): total internal reflection below cos 0.745.
            EXPECT_NEAR(rough_interface_reflectance(smooth, c, 1 / 1.5f),
                        fresnel_dielectric(c, 1 / 1.5f).reflectance, 2e-3)
                << c;
        }
        const RoughCoating coating(smooth, 1.5f);
        EXPECT_NEAR(coating.internal_reflectance(), fresnel_diffuse_reflectance(1 / 1.5f), 2e-3);
        EXPECT_NEAR(coating.transmittance(0.5f), 1 - fresnel_dielectric(0.5f, 1.5f).reflectance,
                    2e-3);
    }
}

TEST(RoughPlastic, InterfaceAlbedosMatchTheRoughDielectricSampler) {
    // The tabulated albedos are integrals of the roughdielectric lobes: estimate the same
    // fractions from that BSDF's own sampler (Importance mode, where weights carry no radiance
    // scaling) and compare. Tolerance: 4 standard errors plus 2e-3 for the quadrature.
    constexpr int n = 200000;
    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (float alpha : {0.1f, 0.5f}) {
            SCOPED_TRACE(std::string(to_string(type)) + " alpha " + std::to_string(alpha));
            const MicrofacetDistribution distribution(type, alpha, alpha);
            const RoughDielectricBsdf interface(distribution, 1.5f, Rgb(1.0f), Rgb(1.0f));
            for (float c : {0.9f, 0.4f, 0.15f, -0.9f, -0.4f}) {
                const Vec3 wo = direction(c);
                Rng rng(StreamKey{41, 0, 1, uint64_t(100 * (c + 2))});
                testing::MeanAccumulator reflected, transmitted;
                for (int i = 0; i < n; ++i) {
                    const float u_lobe = rng.next_1d();
                    std::optional<BsdfSample> s =
                        interface.sample(wo, u_lobe, rng.next_2d(), kImportance);
                    const bool same_side = s && s->wi.z * wo.z > 0;
                    reflected.add(s && same_side ? s->weight.g : 0.0);
                    transmitted.add(s && !same_side ? s->weight.g : 0.0);
                }
                const float eta = c > 0 ? 1.5f : 1 / 1.5f;
                EXPECT_NEAR(rough_interface_reflectance(distribution, std::abs(c), eta),
                            reflected.mean(), 4 * reflected.standard_error() + 2e-3)
                    << c;
                EXPECT_NEAR(rough_interface_transmittance(distribution, std::abs(c), eta),
                            transmitted.mean(), 4 * transmitted.standard_error() + 2e-3)
                    << c;
            }
        }
}

TEST(RoughPlastic, DiffusePartApproachesSmoothPlastic) {
    // Away from the highlight, a nearly smooth rough plastic is the smooth plastic.
    for (bool nonlinear : {false, true}) {
        const Rgb kd(0.8f, 0.4f, 0.1f);
        const PlasticBsdf smooth(kd, Rgb(1.0f), 1.49f, nonlinear);
        const RoughPlasticBsdf rough(
            std::make_shared<RoughCoating>(
                MicrofacetDistribution(MicrofacetType::Beckmann, 1e-3f, 1e-3f), 1.49f),
            kd, Rgb(1.0f), nonlinear);
        for (auto [co, ci] : {std::pair{0.9f, 0.3f}, std::pair{0.5f, 0.7f}, std::pair{0.2f, 0.95f}})
            EXPECT_TRUE(close(rough.f(direction(co, 0.3f), direction(ci, 2.0f), kRadiance),
                              smooth.f(direction(co, 0.3f), direction(ci, 2.0f), kRadiance), 1e-2))
                << co << " " << ci << " nonlinear " << nonlinear;
    }
}

TEST(RoughPlastic, WhiteFurnace) {
    // kd = ks = 1, linear: the coating reflects R(cos) and lets T(cos) into the base, all of
    // which comes out again but for the light the interface loses to masking, so the albedo
    // is at most 1 (tolerance 4 standard errors), and close to 1 for a nearly smooth coating.
    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (float alpha : {0.01f, 0.1f, 0.4f}) {
            const RoughPlasticBsdf white(
                std::make_shared<RoughCoating>(MicrofacetDistribution(type, alpha, alpha), 1.5f),
                Rgb(1.0f), Rgb(1.0f), false);
            for (float c : {0.95f, 0.5f, 0.1f}) {
                SCOPED_TRACE(white.to_string() + " cos " + std::to_string(c));
                const Albedo albedo = estimate_albedo(white, direction(c), kRadiance, 400000, 22);
                EXPECT_LE(albedo.mean.g, 1.0f + 4.0f * albedo.standard_error.g);
                if (alpha == 0.01f && c > 0.2f) {
                    EXPECT_GT(albedo.mean.g, 0.98f);
                }
            }
        }
}

TEST(Blend, MixesValuesAndDensitiesAndPicksChildrenByWeight) {
    const auto diffuse = std::make_shared<DiffuseBsdf>(Rgb(0.8f, 0.5f, 0.2f));
    const auto glossy = std::make_shared<RoughConductorBsdf>(
        MicrofacetDistribution(MicrofacetType::GGX, 0.3f, 0.3f), kCopper, Rgb(1.0f));
    const BlendBsdf blend(diffuse, glossy, 0.3f);
    Rng rng(StreamKey{51, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        const Vec3 wo = warp::square_to_uniform_sphere(rng.next_2d());
        const Vec3 wi = warp::square_to_uniform_sphere(rng.next_2d());
        EXPECT_TRUE(
            close(blend.f(wo, wi, kRadiance),
                  diffuse->f(wo, wi, kRadiance) * 0.7f + glossy->f(wo, wi, kRadiance) * 0.3f, 1e-6,
                  1e-9));
        EXPECT_NEAR(blend.pdf_w(wo, wi).forward,
                    0.7f * diffuse->pdf_w(wo, wi).forward + 0.3f * glossy->pdf_w(wo, wi).forward,
                    1e-5f * (1 + blend.pdf_w(wo, wi).forward));
    }
    // A mirror and a diffuse BSDF: the mirror's delta samples come with probability 1 - w, with
    // the mirror's own weight and that selection probability as their discrete density.
    const BlendBsdf mirror_or_diffuse(std::make_shared<ConductorBsdf>(std::nullopt, Rgb(0.9f)),
                                      diffuse, 0.3f);
    constexpr int n = 40000;
    int mirrored = 0;
    for (int i = 0; i < n; ++i) {
        const float u_lobe = rng.next_1d();
        std::optional<BsdfSample> s =
            mirror_or_diffuse.sample(direction(0.6f), u_lobe, rng.next_2d(), kRadiance);
        ASSERT_TRUE(s);
        if (!s->delta) continue;
        ++mirrored;
        EXPECT_EQ(s->weight, Rgb(0.9f));
        EXPECT_FLOAT_EQ(s->pdf_w.forward, 0.7f);
    }
    EXPECT_NEAR(double(mirrored) / n, 0.7, 4 * std::sqrt(0.7 * 0.3 / n));
}

TEST(Blend, MaskPassesThroughWithOneMinusOpacity) {
    const auto diffuse = std::make_shared<DiffuseBsdf>(Rgb(0.5f));
    const BlendBsdf leaf(std::make_shared<NullBsdf>(), diffuse, 0.25f, true);
    EXPECT_EQ(leaf.lobes(), uint32_t(kLobeNull | kLobeDiffuseReflection));
    EXPECT_FALSE(leaf.is_null());
    const Vec3 wo = direction(0.4f), wi = direction(0.8f, 2.0f);
    EXPECT_TRUE(close(leaf.f(wo, wi, kRadiance), Rgb(0.25f * 0.5f * kInvPi), 1e-6));
    Rng rng(StreamKey{52, 0, 1, 0});
    constexpr int n = 40000;
    int passed = 0;
    for (int i = 0; i < n; ++i) {
        const float u_lobe = rng.next_1d();
        std::optional<BsdfSample> s = leaf.sample(wo, u_lobe, rng.next_2d(), kImportance);
        ASSERT_TRUE(s);
        if (s->lobe != kLobeNull) continue;
        ++passed;
        EXPECT_EQ(s->wi, -wo);
        EXPECT_EQ(s->weight, Rgb(1.0f));
        EXPECT_TRUE(s->delta);
        EXPECT_FLOAT_EQ(s->pdf_w.forward, 0.75f);
    }
    EXPECT_NEAR(double(passed) / n, 0.75, 4 * std::sqrt(0.75 * 0.25 / n));
    // Fully opaque and fully open masks are the nested BSDF and the null BSDF.
    const BlendBsdf opaque(std::make_shared<NullBsdf>(), diffuse, 1.0f, true);
    const BlendBsdf open(std::make_shared<NullBsdf>(), diffuse, 0.0f, true);
    for (float u_lobe : {0.0f, 0.5f, 0.999f}) {
        EXPECT_EQ(opaque.sample(wo, u_lobe, Vec2(0.3f, 0.6f), kRadiance)->lobe,
                  kLobeDiffuseReflection);
        EXPECT_EQ(open.sample(wo, u_lobe, Vec2(0.3f, 0.6f), kRadiance)->lobe, kLobeNull);
    }
}

TEST(Bsdf, PhongSpecularAlbedo) {
    // At normal incidence the normalised lobe integrates cos to exactly 1: albedo = ks for every
    // exponent. At oblique incidence the albedo lies in [ks cos(theta_o), ks]; it equals
    // ks cos(theta_o) once the lobe clears the horizon (large n), because the mean of cos(theta_i)
    // over the lobe is cos(theta_o) (n + 1) / (n + 2).
    for (float n : {1.0f, 10.0f, 90.0f}) {
        SCOPED_TRACE(n);
        const PhongBsdf specular(Rgb(0.0f), Rgb(1.0f), n);
        const Albedo normal = estimate_albedo(specular, Vec3(0, 0, 1), kRadiance, 200000, 31);
        EXPECT_NEAR(normal.mean.r, 1.0f, 4.0f * normal.standard_error.r + 1e-5f);
        const Albedo oblique = estimate_albedo(specular, direction(0.7f), kRadiance, 200000, 32);
        const float tolerance = 4.0f * oblique.standard_error.r + 1e-5f;
        EXPECT_LT(oblique.mean.r, 1.0f);
        EXPECT_GT(oblique.mean.r, 0.7f - tolerance);
        if (n == 90.0f) {
            EXPECT_NEAR(oblique.mean.r, 0.7f, tolerance);
        }
    }
    // The Cornell floor: kd + ks at normal incidence.
    const PhongBsdf floor(Rgb(0.1f), Rgb(0.7f), 90.0f);
    const Albedo albedo = estimate_albedo(floor, Vec3(0, 0, 1), kRadiance, 200000, 33);
    EXPECT_NEAR(albedo.mean.r, 0.8f, 4.0f * albedo.standard_error.r + 1e-5f);
    // f at the mirror direction: kd / pi + ks (n + 2) / (2 pi).
    const Vec3 wo = direction(0.6f);
    EXPECT_TRUE(close(floor.f(wo, reflect_z(wo), kRadiance),
                      Rgb(0.1f / kPi + 0.7f * 92.0f / (2 * kPi)), 1e-5));
}

TEST(Microfacet, ErfinvInvertsErf) {
    for (double y = -0.999999; y < 1.0; y += 0.0123)
        EXPECT_NEAR(std::erf(erfinv(y)), y, 1e-13) << y;
    for (double q : {1e-4, 1e-8, 1e-12})
        EXPECT_NEAR(std::erfc(erfinv(1.0 - q)) / q, 1.0, 1e-3) << q;
    EXPECT_EQ(erfinv(0.0), 0.0);
}

TEST(Microfacet, DistributionsAreNormalised) {
    // Integral of D(m) cos(theta_m) over the hemisphere = 1, by midpoint quadrature in
    // (phi, cos theta).
    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (auto [au, av] : {std::pair{0.3f, 0.3f}, std::pair{0.6f, 0.2f}}) {
            const MicrofacetDistribution d(type, au, av);
            constexpr int n_phi = 256, n_z = 4096;
            double sum = 0;
            for (int i = 0; i < n_phi; ++i)
                for (int j = 0; j < n_z; ++j) {
                    const float z = (j + 0.5f) / n_z, phi = 2 * kPi * (i + 0.5f) / n_phi;
                    const float r = std::sqrt(1 - z * z);
                    sum += d.D(Vec3(r * std::cos(phi), r * std::sin(phi), z)) * z;
                }
            EXPECT_NEAR(sum * 2 * kPi / (n_phi * n_z), 1.0, 2e-3) << to_string(type) << au;
        }
    // Tiny roughness is clamped instead of overflowing.
    const MicrofacetDistribution smooth(MicrofacetType::Beckmann, 0.0f, 0.0f);
    EXPECT_EQ(smooth.alpha_u(), MicrofacetDistribution::kMinAlpha);
    EXPECT_TRUE(std::isfinite(smooth.D(Vec3(0, 0, 1))));
}

// --- factory -----------------------------------------------------------------------------

const SourceLocation kPluginLine{"scene.xml", 10};
const SourceLocation kParamLine{"scene.xml", 12};

Properties bsdf_props(const std::string& type) {
    return Properties("bsdf", type, kPluginLine);
}

std::string error_of(const Properties& props) {
    try {
        make_bsdf(props);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(BsdfFactory, UnknownTypeNamesTheSupportedOnes) {
    EXPECT_EQ(error_of(bsdf_props("velvet")),
              "scene.xml:10: unknown bsdf type \"velvet\" (supported: diffuse, twosided, "
              "diffusetransmission, hair, conductor, roughconductor, dielectric, "
              "roughdielectric, thindielectric, plastic, "
              "roughplastic, phong, null, blendbsdf, mask, normalmap, bumpmap)");
}

TEST(BsdfFactory, BuildsEveryTypeWithDefaults) {
    for (const char* type :
         {"diffuse", "diffusetransmission", "hair", "conductor", "roughconductor", "dielectric",
          "roughdielectric", "thindielectric", "plastic", "roughplastic", "phong"}) {
        Properties props = bsdf_props(type);
        std::shared_ptr<const Bsdf> bsdf = make_bsdf(props);
        ASSERT_TRUE(bsdf) << type;
        EXPECT_NO_THROW(props.check_all_used());
    }
    Properties twosided = bsdf_props("twosided");
    twosided.nested_bsdfs.push_back(make_bsdf(bsdf_props("diffuse")));
    EXPECT_TRUE(make_bsdf(twosided));
    twosided.nested_bsdfs.push_back(make_bsdf(bsdf_props("phong")));
    EXPECT_TRUE(make_bsdf(twosided));
}

TEST(BsdfFactory, ReadsEveryDocumentedParameter) {
    Properties rough = bsdf_props("roughconductor");
    rough.set("distribution", std::string("ggx"), kParamLine);
    rough.set("alpha_u", 0.1f, kParamLine);
    rough.set("alpha_v", 0.3f, kParamLine);
    rough.set("sample_visible", false, kParamLine);
    rough.set("eta", Rgb(0.2f, 0.9f, 1.1f), kParamLine);
    rough.set("k", Rgb(3.9f, 2.4f, 2.1f), kParamLine);
    rough.set("specular_reflectance", 0.8f, kParamLine);
    make_bsdf(rough);
    EXPECT_NO_THROW(rough.check_all_used());

    Properties plastic = bsdf_props("plastic");
    plastic.set("diffuse_reflectance", Rgb(0.1f, 0.2f, 0.3f), kParamLine);
    plastic.set("specular_reflectance", 0.5f, kParamLine);
    plastic.set("int_ior", std::string("acrylic glass"), kParamLine);
    plastic.set("ext_ior", 1.0f, kParamLine);
    plastic.set("nonlinear", true, kParamLine);
    make_bsdf(plastic);
    EXPECT_NO_THROW(plastic.check_all_used());

    Properties rough_plastic = bsdf_props("roughplastic");
    rough_plastic.set("distribution", std::string("ggx"), kParamLine);
    rough_plastic.set("alpha", 0.2f, kParamLine);
    rough_plastic.set("sample_visible", false, kParamLine);
    rough_plastic.set("diffuse_reflectance", Rgb(0.1f, 0.2f, 0.3f), kParamLine);
    rough_plastic.set("specular_reflectance", 0.5f, kParamLine);
    rough_plastic.set("int_ior", 1.6f, kParamLine);
    rough_plastic.set("ext_ior", std::string("water"), kParamLine);
    rough_plastic.set("nonlinear", true, kParamLine);
    EXPECT_EQ(make_bsdf(rough_plastic)->to_string(),
              "roughplastic(ggx, alpha 0.2, diffuse_reflectance [0.1, 0.2, 0.3], "
              "specular_reflectance [0.5, 0.5, 0.5], eta 1.2003, nonlinear)");
    EXPECT_NO_THROW(rough_plastic.check_all_used());

    Properties blend = bsdf_props("blendbsdf");
    blend.set("weight", 0.25f, kParamLine);
    blend.nested_bsdfs.push_back(make_bsdf(bsdf_props("diffuse")));
    blend.nested_bsdfs.push_back(make_bsdf(bsdf_props("conductor")));
    EXPECT_EQ(make_bsdf(blend)->to_string(),
              "blendbsdf(weight 0.25, diffuse(reflectance [0.5, 0.5, 0.5]), conductor(no fresnel, "
              "specular_reflectance [1, 1, 1]))");
    EXPECT_NO_THROW(blend.check_all_used());
    Properties mask = bsdf_props("mask");
    mask.set("opacity", 1.5f, kParamLine);  // clamped to [0, 1], as Mitsuba
    mask.nested_bsdfs.push_back(make_bsdf(bsdf_props("diffuse")));
    EXPECT_EQ(make_bsdf(mask)->to_string(),
              "mask(opacity 1, diffuse(reflectance [0.5, 0.5, 0.5]))");
    EXPECT_NO_THROW(mask.check_all_used());

    Properties phong = bsdf_props("phong");
    phong.set("diffuse_reflectance", 0.1f, kParamLine);
    phong.set("specular_reflectance", 0.7f, kParamLine);
    phong.set("exponent", int64_t(90), kParamLine);
    std::shared_ptr<const Bsdf> floor = make_bsdf(phong);
    EXPECT_NO_THROW(phong.check_all_used());
    const Vec3 wo = direction(0.6f);
    EXPECT_TRUE(close(floor->f(wo, reflect_z(wo), kRadiance),
                      Rgb(0.1f / kPi + 0.7f * 92.0f / (2 * kPi)), 1e-5));

    Properties mirror = bsdf_props("conductor");
    mirror.set("material", std::string("none"), kParamLine);
    std::optional<BsdfSample> s =
        make_bsdf(mirror)->sample(direction(0.3f), 0.5f, Vec2(), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->weight, Rgb(1.0f));
}

TEST(BsdfFactory, RejectsBadValuesNamingTheField) {
    Properties alpha = bsdf_props("roughconductor");
    alpha.set("alpha", -0.1f, kParamLine);
    EXPECT_EQ(error_of(alpha),
              "scene.xml:12: bsdf \"roughconductor\", parameter \"alpha\": roughness must be "
              "finite and non-negative (got -0.1)");

    Properties exponent = bsdf_props("phong");
    exponent.set("exponent", -1.0f, kParamLine);
    EXPECT_NE(error_of(exponent).find("scene.xml:12: bsdf \"phong\", parameter \"exponent\""),
              std::string::npos);

    Properties nan = bsdf_props("diffuse");
    nan.set("reflectance", Rgb(0.5f, std::numeric_limits<float>::quiet_NaN(), 0.5f), kParamLine);
    EXPECT_NE(error_of(nan).find("parameter \"reflectance\": must be finite"), std::string::npos);

    Properties ior = bsdf_props("dielectric");
    ior.set("int_ior", 0.0f, kParamLine);
    EXPECT_NE(error_of(ior).find("parameter \"int_ior\": an index of refraction must be positive"),
              std::string::npos);

    Properties distribution = bsdf_props("roughdielectric");
    distribution.set("distribution", std::string("phong"), kParamLine);
    EXPECT_NE(error_of(distribution).find("unknown distribution \"phong\""), std::string::npos);

    Properties metal = bsdf_props("conductor");
    metal.set("material", std::string("Unobtainium"), kParamLine);
    EXPECT_NE(error_of(metal).find("parameter \"material\": unknown conductor \"Unobtainium\""),
              std::string::npos);

    Properties both = bsdf_props("conductor");
    both.set("material", std::string("Au"), kParamLine);
    both.set("eta", 1.0f, kParamLine);
    EXPECT_NE(error_of(both).find("not both"), std::string::npos);

    Properties matched = bsdf_props("roughdielectric");
    matched.set("int_ior", 1.3f, kParamLine);
    matched.set("ext_ior", 1.3f, kParamLine);
    EXPECT_NE(error_of(matched).find("parameter \"int_ior\""), std::string::npos);

    Properties anisotropic = bsdf_props("roughplastic");
    anisotropic.set("alpha_u", 0.1f, kParamLine);
    anisotropic.set("alpha_v", 0.2f, kParamLine);
    EXPECT_EQ(error_of(anisotropic),
              "scene.xml:12: bsdf \"roughplastic\", parameter \"alpha_u\": roughplastic is "
              "isotropic (as in Mitsuba 3): give alpha");
    Properties invisible = bsdf_props("roughplastic");
    invisible.set("int_ior", 1.2f, kParamLine);
    invisible.set("ext_ior", 1.2f, kParamLine);
    EXPECT_NE(error_of(invisible).find("parameter \"int_ior\": equals ext_ior"), std::string::npos);

    EXPECT_EQ(error_of(bsdf_props("blendbsdf")),
              "scene.xml:10: bsdf \"blendbsdf\" needs two nested bsdfs, got 0");
    Properties two_masked = bsdf_props("mask");
    two_masked.nested_bsdfs.push_back(make_bsdf(bsdf_props("diffuse")));
    two_masked.nested_bsdfs.push_back(make_bsdf(bsdf_props("diffuse")));
    EXPECT_EQ(error_of(two_masked), "scene.xml:10: bsdf \"mask\" needs one nested bsdf, got 2");

    EXPECT_NE(error_of(bsdf_props("twosided")).find("scene.xml:10: bsdf \"twosided\" needs one"),
              std::string::npos);
    Properties glass_twosided = bsdf_props("twosided");
    glass_twosided.nested_bsdfs.push_back(make_bsdf(bsdf_props("dielectric")));
    EXPECT_NE(error_of(glass_twosided).find("cannot wrap the transmissive"), std::string::npos);
}

TEST(BsdfFactory, NamedIors) {
    EXPECT_EQ(*lookup_dielectric_ior("bk7"), 1.5046f);
    EXPECT_EQ(*lookup_dielectric_ior("water"), 1.333f);
    EXPECT_EQ(*lookup_dielectric_ior("Carbon Dioxide"), 1.00045f);
    EXPECT_EQ(*lookup_dielectric_ior("diamond"), 2.419f);
    EXPECT_FALSE(lookup_dielectric_ior("unobtainium"));

    auto eta_of = [](Properties props) {
        return std::dynamic_pointer_cast<const DielectricBsdf>(make_bsdf(props))->eta();
    };
    EXPECT_FLOAT_EQ(eta_of(bsdf_props("dielectric")), 1.5046f / 1.000277f);
    Properties water = bsdf_props("dielectric");
    water.set("int_ior", std::string("water"), kParamLine);
    water.set("ext_ior", std::string("vacuum"), kParamLine);
    EXPECT_FLOAT_EQ(eta_of(water), 1.333f);
    Properties numbers = bsdf_props("dielectric");
    numbers.set("int_ior", 1.6f, kParamLine);
    numbers.set("ext_ior", int64_t(1), kParamLine);
    EXPECT_FLOAT_EQ(eta_of(numbers), 1.6f);

    Properties unknown = bsdf_props("dielectric");
    unknown.set("int_ior", std::string("unobtainium"), kParamLine);
    const std::string message = error_of(unknown);
    EXPECT_EQ(message.find("scene.xml:12: bsdf \"dielectric\", parameter \"int_ior\": unknown IOR "
                           "name \"unobtainium\" (known: vacuum, helium"),
              0u)
        << message;
}

}  // namespace
}  // namespace render
