// pbrt-v4's `diffusetransmission` (core/materials/diffuse_transmission.h), beyond the checks
// every BSDF gets (bsdf_test.cpp: sample/pdf/f agreement, reciprocity, energy;
// bsdf_chi_square_test.cpp: the sampled directions follow pdf_w):
//   - the directional albedo splits exactly into R reflected and T transmitted, from either side;
//   - pbrt-v4's defaults (0.25, 0.25) and `scale` with its clamp to [0, 1];
//   - the pbrt loader maps the material with its textures.

#include <gtest/gtest.h>

#include <cmath>

#include "core/base/error.h"
#include "core/base/properties.h"
#include "core/materials/bsdf_factory.h"
#include "core/materials/diffuse_transmission.h"
#include "core/sampling/rng.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

Vec3 direction(float cos_theta, float phi = 0.4f) {
    const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
    return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

// Every sample's weight is R / p_reflect or T / (1 - p_reflect), so the expected reflected and
// transmitted albedos are exactly R and T. Tolerance: 5 standard errors of each mean.
TEST(DiffuseTransmission, AlbedoSplitsIntoReflectanceAndTransmittance) {
    const Rgb r(0.2f, 0.5f, 0.8f), t(0.6f, 0.3f, 0.1f);
    const DiffuseTransmissionBsdf bsdf(r, t);
    for (const float c : {0.8f, 0.2f, -0.6f}) {
        SCOPED_TRACE(c);
        const Vec3 wo = direction(c);
        Rng rng(StreamKey{21, 0, 0, uint64_t(10 * (c + 1))});
        testing::MeanAccumulator reflected[3], transmitted[3];
        for (int i = 0; i < 200000; ++i) {
            const float u_lobe = rng.next_1d();
            const auto s = bsdf.sample(wo, u_lobe, rng.next_2d(), TransportMode::Radiance);
            ASSERT_TRUE(s);
            const bool same = s->wi.z * wo.z > 0;
            EXPECT_EQ(s->lobe, same ? kLobeDiffuseReflection : kLobeDiffuseTransmission);
            for (int k = 0; k < 3; ++k) {
                reflected[k].add(same ? s->weight[k] : 0.0);
                transmitted[k].add(same ? 0.0 : s->weight[k]);
            }
        }
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(reflected[k].mean(), r[k], 5 * reflected[k].standard_error());
            EXPECT_NEAR(transmitted[k].mean(), t[k], 5 * transmitted[k].standard_error());
        }
    }
    // The values: R / pi on one side, T / pi across, in both transport modes.
    const Vec3 a = direction(0.7f), b = direction(0.3f, 2.0f), below = direction(-0.5f, 1.0f);
    for (const TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
        EXPECT_NEAR(bsdf.f(a, b, mode).g, 0.5 / M_PI, 1e-7);
        EXPECT_NEAR(bsdf.f(a, below, mode).g, 0.3 / M_PI, 1e-7);
        EXPECT_NEAR(bsdf.f(below, a, mode).r, 0.6 / M_PI, 1e-7);
    }
    EXPECT_EQ(bsdf.lobes(), kLobeDiffuseReflection | kLobeDiffuseTransmission);
}

TEST(DiffuseTransmission, PbrtDefaultsAndScale) {
    const SourceLocation at{"scene.pbrt", 3};
    {
        Properties props("bsdf", "diffusetransmission", at);
        auto bsdf = std::dynamic_pointer_cast<const DiffuseTransmissionBsdf>(make_bsdf(props));
        ASSERT_TRUE(bsdf);
        EXPECT_EQ(bsdf->reflectance(), Rgb(0.25f));
        EXPECT_EQ(bsdf->transmittance(), Rgb(0.25f));
    }
    {
        Properties props("bsdf", "diffusetransmission", at);
        props.set("reflectance", Rgb(0.1f, 0.2f, 0.4f), at);
        props.set("transmittance", Rgb(0.3f, 0.5f, 0.0f), at);
        props.set("scale", 3.0f, at);
        auto bsdf = std::dynamic_pointer_cast<const DiffuseTransmissionBsdf>(make_bsdf(props));
        ASSERT_TRUE(bsdf);
        EXPECT_NEAR(bsdf->reflectance().g, 0.6f, 1e-6);
        EXPECT_EQ(bsdf->reflectance().b, 1.0f);  // 1.2 clamped, as pbrt-v4 does
        EXPECT_EQ(bsdf->transmittance().g, 1.0f);
        EXPECT_NO_THROW(props.check_all_used());
    }
    {
        Properties props("bsdf", "diffusetransmission", at);
        props.set("transmittance", Rgb(-0.1f), at);
        EXPECT_THROW(make_bsdf(props), SceneError);
    }
}

}  // namespace
}  // namespace render
