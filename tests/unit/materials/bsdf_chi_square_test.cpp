// Chi-square goodness-of-fit tests of every non-delta BSDF lobe: the directions sample()
// returns must follow the density pdf_w() reports. For BSDFs with delta lobes only the non-delta
// samples are histogrammed; pdf_w() reports the non-delta density including its selection
// probability, so both sides describe the same sub-distribution (integral < 1).

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/materials/blend.h"
#include "core/materials/bsdf_factory.h"
#include "core/materials/conductor.h"
#include "core/materials/diffuse.h"
#include "core/materials/diffuse_transmission.h"
#include "core/materials/microfacet.h"
#include "core/materials/null_bsdf.h"
#include "core/materials/phong.h"
#include "core/materials/plastic.h"
#include "core/materials/rough_conductor.h"
#include "core/materials/rough_dielectric.h"
#include "core/materials/rough_plastic.h"
#include "core/materials/thin_dielectric.h"
#include "core/materials/twosided.h"
#include "core/textures/texture_factory.h"
#include "tests/support/chi_square.h"

namespace render {
namespace {

using testing::chi_square_test_discrete;
using testing::chi_square_test_sphere;
using testing::ChiSquareDeclaration;
using testing::ChiSquareFamily;
using testing::ChiSquareOptions;
using testing::ChiSquareResult;

// An incident direction with the given cosine, at an azimuth away from the histogram's phi = 0
// seam.
Vec3 incident(float cos_theta) {
    const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
    const float phi = 0.7f;
    return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

struct ChiSquareCase {
    std::string name;
    std::function<std::shared_ptr<const Bsdf>()> make;
    float cos_theta_o;
    TransportMode mode = TransportMode::Radiance;
    // Narrow lobes need finer cells for the harness' per-cell quadrature to be accurate.
    bool narrow = false;
};

// gtest prints parameters of failed tests; the name says it all.
void PrintTo(const ChiSquareCase& c, std::ostream* os) {
    *os << c.name;
}

std::shared_ptr<const Bsdf> rough_conductor(MicrofacetType type, float alpha_u, float alpha_v,
                                            bool visible = true) {
    return std::make_shared<RoughConductorBsdf>(
        MicrofacetDistribution(type, alpha_u, alpha_v, visible),
        ConductorIor{Rgb(0.2f, 0.9f, 1.1f), Rgb(3.9f, 2.4f, 2.1f)}, Rgb(1.0f));
}

std::shared_ptr<const Bsdf> rough_dielectric(MicrofacetType type, float alpha) {
    return std::make_shared<RoughDielectricBsdf>(MicrofacetDistribution(type, alpha, alpha), 1.5f,
                                                 Rgb(1.0f), Rgb(1.0f));
}

std::shared_ptr<const Bsdf> rough_plastic(MicrofacetType type, float alpha, const Rgb& kd,
                                          const Rgb& ks, bool nonlinear = false,
                                          bool visible = true) {
    auto coating =
        std::make_shared<RoughCoating>(MicrofacetDistribution(type, alpha, alpha, visible), 1.49f);
    return std::make_shared<RoughPlasticBsdf>(coating, kd, ks, nonlinear);
}

// A material of `type` whose parameter `param` is a checkerboard of c0 and c1 (plus `extra`
// string parameters), resolved at uv (0.75, 0.25), in a color1 square, as the scene resolves a
// textured material at a hit.
std::shared_ptr<const Bsdf> textured(
    const std::string& type, const std::string& param, float c0, float c1,
    const std::vector<std::pair<std::string, std::string>>& extra = {}) {
    const SourceLocation at{"chi_square", 1};
    Properties checker("texture", "checkerboard", at);
    checker.set("color0", c0, at);
    checker.set("color1", c1, at);
    Properties props("bsdf", type, at);
    props.set(param, make_texture(checker), at);
    for (const auto& [name, value] : extra) props.set(name, value, at);
    const std::shared_ptr<const Bsdf> material = make_bsdf(props);
    props.check_all_used();
    return material->at(Vec2(0.75f, 0.25f));
}

// A blendbsdf of a diffuse and a rough conductor whose weight is a checkerboard of w0 and
// w1, resolved at uv (0.75, 0.25) (a color1 square) as the scene resolves it at a hit.
std::shared_ptr<const Bsdf> textured_blend(float w0, float w1) {
    const SourceLocation at{"chi_square", 1};
    Properties checker("texture", "checkerboard", at);
    checker.set("color0", w0, at);
    checker.set("color1", w1, at);
    Properties props("bsdf", "blendbsdf", at);
    props.set("weight", make_texture(checker), at);
    props.nested_bsdfs.push_back(std::make_shared<DiffuseBsdf>(Rgb(0.5f)));
    props.nested_bsdfs.push_back(rough_conductor(MicrofacetType::Beckmann, 0.3f, 0.3f));
    const std::shared_ptr<const Bsdf> material = make_bsdf(props);
    props.check_all_used();
    return material->at(Vec2(0.75f, 0.25f));
}

std::string cos_name(float c) {
    std::string s = std::to_string(c);
    for (char& ch : s)
        if (ch == '.' || ch == '-') ch = ch == '.' ? 'p' : 'm';
    return s.substr(0, c < 0 ? 4 : 3);
}

std::vector<ChiSquareCase> all_cases() {
    std::vector<ChiSquareCase> cases;
    const float angles[] = {0.9f, 0.5f, 0.1f};
    for (float c : angles)
        cases.push_back(
            {"diffuse_" + cos_name(c), [] { return std::make_shared<DiffuseBsdf>(Rgb(0.5f)); }, c});
    // Both lobes, from either side; transmission only.
    for (float c : {0.9f, 0.5f, 0.1f, -0.3f, -0.8f})
        cases.push_back({"diffusetransmission_" + cos_name(c),
                         [] {
                             return std::make_shared<DiffuseTransmissionBsdf>(
                                 Rgb(0.2f, 0.5f, 0.8f), Rgb(0.6f, 0.3f, 0.1f));
                         },
                         c});
    cases.push_back({"diffusetransmission_transmit_only",
                     [] { return std::make_shared<DiffuseTransmissionBsdf>(Rgb(0.0f), Rgb(0.7f)); },
                     0.4f});
    for (float c : angles)
        cases.push_back({"twosided_diffuse_below_" + cos_name(c),
                         [] {
                             auto child = std::make_shared<DiffuseBsdf>(Rgb(0.5f));
                             return std::make_shared<TwoSidedBsdf>(child, nullptr);
                         },
                         -c});

    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (float alpha : {0.1f, 0.3f, 0.7f})
            for (float c : angles)
                cases.push_back({std::string("roughconductor_") + to_string(type) + "_a" +
                                     cos_name(alpha) + "_" + cos_name(c),
                                 [=] { return rough_conductor(type, alpha, alpha); }, c,
                                 TransportMode::Radiance, alpha < 0.2f});
    cases.push_back({"roughconductor_beckmann_anisotropic",
                     [] { return rough_conductor(MicrofacetType::Beckmann, 0.1f, 0.4f); }, 0.5f});
    cases.push_back({"roughconductor_ggx_anisotropic",
                     [] { return rough_conductor(MicrofacetType::GGX, 0.4f, 0.1f); }, 0.5f});
    cases.push_back({"roughconductor_beckmann_all_normals",
                     [] { return rough_conductor(MicrofacetType::Beckmann, 0.3f, 0.3f, false); },
                     0.5f});
    cases.push_back({"roughconductor_ggx_all_normals_anisotropic",
                     [] { return rough_conductor(MicrofacetType::GGX, 0.2f, 0.5f, false); }, 0.5f});

    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (float alpha : {0.1f, 0.5f})
            for (float c : {0.9f, 0.5f, 0.1f, -0.9f, -0.5f, -0.1f})
                cases.push_back({std::string("roughdielectric_") + to_string(type) + "_a" +
                                     cos_name(alpha) + "_" + cos_name(c),
                                 [=] { return rough_dielectric(type, alpha); }, c,
                                 // Importance mode from inside: the radiance scaling does not
                                 // change directions, only weights, but cover both modes.
                                 c < 0 ? TransportMode::Importance : TransportMode::Radiance,
                                 alpha < 0.2f});

    for (float c : angles)
        cases.push_back(
            {"plastic_" + cos_name(c),
             [] { return std::make_shared<PlasticBsdf>(Rgb(0.5f), Rgb(1.0f), 1.49f, false); }, c});
    cases.push_back(
        {"plastic_nonlinear_dark_specular",
         [] { return std::make_shared<PlasticBsdf>(Rgb(0.8f, 0.4f, 0.1f), Rgb(0.3f), 1.7f, true); },
         0.3f});

    // Rough plastic: a glossy and a diffuse lobe picked by the coating's transmittance.
    for (MicrofacetType type : {MicrofacetType::Beckmann, MicrofacetType::GGX})
        for (float alpha : {0.1f, 0.4f})
            for (float c : angles)
                cases.push_back({std::string("roughplastic_") + to_string(type) + "_a" +
                                     cos_name(alpha) + "_" + cos_name(c),
                                 [=] { return rough_plastic(type, alpha, Rgb(0.5f), Rgb(1.0f)); },
                                 c, TransportMode::Radiance, alpha < 0.2f});
    cases.push_back({"roughplastic_ggx_all_normals_nonlinear_importance",
                     [] {
                         return rough_plastic(MicrofacetType::GGX, 0.2f, Rgb(0.9f, 0.3f, 0.1f),
                                              Rgb(0.6f), true, false);
                     },
                     0.6f, TransportMode::Importance});
    cases.push_back(
        {"roughplastic_specular_only",
         [] { return rough_plastic(MicrofacetType::Beckmann, 0.3f, Rgb(0.0f), Rgb(1.0f)); }, 0.5f});

    // Blends: the mixture of the children's densities, picked by weight.
    for (float c : angles)
        cases.push_back({"blend_diffuse_roughconductor_" + cos_name(c),
                         [] {
                             return std::make_shared<BlendBsdf>(
                                 std::make_shared<DiffuseBsdf>(Rgb(0.5f)),
                                 rough_conductor(MicrofacetType::GGX, 0.2f, 0.2f), 0.35f);
                         },
                         c});
    for (float c : {0.6f, -0.6f})
        cases.push_back({"blend_roughplastic_roughdielectric_" + cos_name(c),
                         [] {
                             return std::make_shared<BlendBsdf>(
                                 rough_plastic(MicrofacetType::GGX, 0.3f, Rgb(0.4f), Rgb(1.0f)),
                                 rough_dielectric(MicrofacetType::Beckmann, 0.3f), 0.6f);
                         },
                         c});
    cases.push_back({"blend_mirror_phong",
                     [] {
                         return std::make_shared<BlendBsdf>(
                             std::make_shared<ConductorBsdf>(std::nullopt, Rgb(1.0f)),
                             std::make_shared<PhongBsdf>(Rgb(0.3f), Rgb(0.5f), 10.0f), 0.5f);
                     },
                     0.5f});
    cases.push_back({"mask_diffuse",
                     [] {
                         return std::make_shared<BlendBsdf>(
                             std::make_shared<NullBsdf>(), std::make_shared<DiffuseBsdf>(Rgb(0.5f)),
                             0.7f, true);
                     },
                     0.5f});
    cases.push_back({"textured_blendbsdf_weight", [] { return textured_blend(0.1f, 0.8f); }, 0.5f});

    for (float exponent : {1.0f, 10.0f, 90.0f})
        for (float c : angles)
            cases.push_back(
                {"phong_n" + std::to_string(int(exponent)) + "_" + cos_name(c),
                 [=] { return std::make_shared<PhongBsdf>(Rgb(0.1f), Rgb(0.7f), exponent); }, c,
                 TransportMode::Radiance, exponent > 50});
    cases.push_back({"phong_specular_only_n90",
                     [] { return std::make_shared<PhongBsdf>(Rgb(0.0f), Rgb(0.7f), 90.0f); }, 0.5f,
                     TransportMode::Radiance, true});
    cases.push_back({"phong_specular_only_n10_grazing",
                     [] { return std::make_shared<PhongBsdf>(Rgb(0.0f), Rgb(0.7f), 10.0f); },
                     0.1f});
    // Textured materials: the plain BSDF a hit resolves them into samples as it evaluates.
    cases.push_back(
        {"textured_diffuse", [] { return textured("diffuse", "reflectance", 0.2f, 0.9f); }, 0.6f});
    cases.push_back(
        {"textured_roughconductor_ggx_alpha",
         [] {
             return textured("roughconductor", "alpha", 0.05f, 0.5f, {{"distribution", "ggx"}});
         },
         0.4f});
    cases.push_back({"textured_plastic_diffuse_reflectance",
                     [] { return textured("plastic", "diffuse_reflectance", 0.1f, 0.8f); }, 0.5f});
    cases.push_back({"textured_roughplastic_diffuse_reflectance",
                     [] {
                         return textured("roughplastic", "diffuse_reflectance", 0.05f, 0.9f,
                                         {{"distribution", "ggx"}});
                     },
                     0.5f});
    cases.push_back({"textured_roughdielectric_alpha_inside",
                     [] { return textured("roughdielectric", "alpha", 0.05f, 0.4f); }, -0.5f,
                     TransportMode::Importance});
    cases.push_back(
        {"phong_diffuse_heavy_n30",
         [] { return std::make_shared<PhongBsdf>(Rgb(0.8f, 0.5f, 0.2f), Rgb(0.05f), 30.0f); },
         0.7f});
    return cases;
}

// The microfacet distributions' own samplers, tested against their densities (these also check
// that the visible-normal density integrates to one, i.e. that G1 is the exact Smith term).
struct MicrofacetCase {
    std::string name;
    MicrofacetType type;
    float alpha_u, alpha_v;
    bool visible;
    float cos_theta;
};

void PrintTo(const MicrofacetCase& c, std::ostream* os) {
    *os << c.name;
}

std::vector<MicrofacetCase> microfacet_cases() {
    return {
        {"beckmann_visible", MicrofacetType::Beckmann, 0.5f, 0.5f, true, 0.4f},
        {"beckmann_visible_anisotropic", MicrofacetType::Beckmann, 0.8f, 0.2f, true, 0.2f},
        {"ggx_visible", MicrofacetType::GGX, 0.5f, 0.5f, true, 0.4f},
        {"ggx_visible_anisotropic", MicrofacetType::GGX, 0.2f, 0.8f, true, 0.2f},
        {"beckmann_all_normals", MicrofacetType::Beckmann, 0.5f, 0.5f, false, 0.4f},
        {"ggx_all_normals", MicrofacetType::GGX, 0.5f, 0.5f, false, 0.4f},
    };
}

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h):
// one per instance of each parameterised test.
ChiSquareFamily family;
const ChiSquareDeclaration kBsdfChecks(family, "BsdfChiSquare.SamplesFollowPdf", 1,
                                       int(all_cases().size()));
const ChiSquareDeclaration kMicrofacetChecks(family, "MicrofacetChiSquare.NormalsFollowPdf", 1,
                                             int(microfacet_cases().size()));

ChiSquareOptions options_for(uint64_t seed, bool narrow) {
    ChiSquareOptions options;
    options.resolution_x = narrow ? 128 : 64;  // phi
    options.resolution_y = narrow ? 64 : 32;   // cos theta; z = 0 falls on a cell boundary
    options.sample_count = 250000;
    options.seed = seed;
    return options;
}

class BsdfChiSquare : public ::testing::TestWithParam<ChiSquareCase> {};

TEST_P(BsdfChiSquare, SamplesFollowPdf) {
    const ChiSquareCase& c = GetParam();
    const std::shared_ptr<const Bsdf> bsdf = c.make();
    const Vec3 wo = incident(c.cos_theta_o);
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        const float u_lobe = rng.next_1d();
        const Vec2 u = rng.next_2d();
        std::optional<BsdfSample> s = bsdf->sample(wo, u_lobe, u, c.mode);
        if (!s || s->delta) return std::nullopt;
        return s->wi;
    };
    auto pdf = [&](const Vec3& wi) { return double(bsdf->pdf_w(wo, wi).forward); };
    const ChiSquareResult result = chi_square_test_sphere(
        family, sample, pdf, options_for(std::hash<std::string>()(c.name), c.narrow));
    EXPECT_TRUE(result.passed) << bsdf->to_string() << ", wo = " << wo << ": " << result.message;
    EXPECT_LE(result.pdf_integral, 1.0 + 1e-3) << result.message;
}

INSTANTIATE_TEST_SUITE_P(Bsdfs, BsdfChiSquare, ::testing::ValuesIn(all_cases()),
                         [](const auto& info) { return info.param.name; });

class MicrofacetChiSquare : public ::testing::TestWithParam<MicrofacetCase> {};

TEST_P(MicrofacetChiSquare, NormalsFollowPdf) {
    const MicrofacetCase& c = GetParam();
    const MicrofacetDistribution distribution(c.type, c.alpha_u, c.alpha_v, c.visible);
    const Vec3 w = incident(c.cos_theta);
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        return distribution.sample(w, rng.next_2d());
    };
    auto pdf = [&](const Vec3& m) { return double(distribution.pdf(w, m)); };
    const ChiSquareResult result = chi_square_test_sphere(
        family, sample, pdf, options_for(std::hash<std::string>()(c.name), false));
    EXPECT_TRUE(result.passed) << result.message;
    // Every sample is a valid normal, so the density must integrate to one.
    EXPECT_NEAR(result.pdf_integral, 1.0, 2e-3) << result.message;
}

INSTANTIATE_TEST_SUITE_P(Distributions, MicrofacetChiSquare,
                         ::testing::ValuesIn(microfacet_cases()),
                         [](const auto& info) { return info.param.name; });

// thindielectric has two delta lobes and no density to histogram: its sampler is tested on
// which lobe it picks and where the lobe points. Cells are (incident direction, lobe), four
// directions from both sides with equal shares of the samples; the expected fractions are the
// slab reflectance R' = R + T^2 R / (1 - R^2) computed here from the Fresnel formula, not from
// the BSDF's own helper.
CHI_SQUARE_TEST(family, ThinDielectricChiSquare, LobesFollowSlabFresnel, 1) {
    const float eta = 1.5f;
    const ThinDielectricBsdf pane(eta, Rgb(1.0f), Rgb(1.0f));
    const float cosines[] = {0.9f, 0.3f, 0.08f, -0.2f};
    constexpr int per_direction = 50000;
    std::vector<double> observed, probability;
    Rng rng(StreamKey{21, 0, 1, 0});
    for (float c : cosines) {
        const Vec3 wo = incident(c);
        // Unpolarised single-interface Fresnel reflectance from outside at |cos| = ci.
        const double ci = std::abs(c), sin_t = std::sqrt(1 - ci * ci) / eta;
        const double ct = std::sqrt(1 - sin_t * sin_t);
        const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
        const double r = 0.5 * (rs * rs + rp * rp), t = 1 - r;
        const double slab = r + t * t * r / (1 - r * r);
        double reflected = 0, transmitted = 0;
        for (int i = 0; i < per_direction; ++i) {
            const float u_lobe = rng.next_1d();
            std::optional<BsdfSample> s =
                pane.sample(wo, u_lobe, rng.next_2d(), TransportMode::Radiance);
            ASSERT_TRUE(s && s->delta);
            if (s->lobe == kLobeDeltaReflection) {
                ASSERT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));  // the mirror direction
                reflected += 1;
            } else {
                ASSERT_EQ(s->wi, -wo);
                transmitted += 1;
            }
        }
        observed.insert(observed.end(), {reflected, transmitted});
        const double share = 1.0 / std::size(cosines);
        probability.insert(probability.end(), {share * slab, share * (1 - slab)});
    }
    const ChiSquareResult result = chi_square_test_discrete(
        family, observed, probability, per_direction * int(std::size(cosines)));
    EXPECT_TRUE(result.passed) << result.message;
}

}  // namespace
}  // namespace render
