// Textured materials: the loader attaches nested and referenced textures to BSDF parameters,
// the scene resolves a textured material at each hit into the plain BSDF of that point (and
// leaves untextured materials untouched), the resolved BSDF outlives its interaction, and bad
// texture input gives located errors.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/base/error.h"
#include "core/materials/diffuse.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

// A rectangle ([-1, 1]^2 at z = 0, uv = ((x + 1) / 2, (y + 1) / 2)) with the given bsdf; any
// top-level elements before it.
std::unique_ptr<Scene> plane_with(const std::string& bsdf, const std::string& before = "") {
    return load_scene_from_string(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" "
        "value=\"45\"/></sensor>" +
            before + "<shape type=\"rectangle\">" + bsdf + "</shape></scene>",
        ".");
}

const char* kChecker = R"(<texture type="checkerboard" name="reflectance">
    <rgb name="color0" value="0.8, 0.4, 0.1"/><rgb name="color1" value="0.1, 0.3, 0.6"/>
  </texture>)";

// The interaction where a ray straight down hits the plane at (x, y).
SurfaceInteraction hit(const Scene& scene, float x, float y) {
    SurfaceInteraction si;
    EXPECT_TRUE(scene.intersect(Ray(Vec3(x, y, 1), Vec3(0, 0, -1)), si));
    return si;
}

Rgb diffuse_reflectance(const SurfaceInteraction& si) {
    const auto* d = dynamic_cast<const DiffuseBsdf*>(si.bsdf);
    EXPECT_NE(d, nullptr) << si.bsdf->to_string();
    return d ? d->reflectance() : Rgb(-1.0f);
}

TEST(TexturedMaterial, NestedTextureIsResolvedAtEachHit) {
    auto scene = plane_with(std::string("<bsdf type=\"diffuse\">") + kChecker + "</bsdf>");
    const Bsdf* material = scene->shapes()[0]->bsdf;
    EXPECT_TRUE(material->varies());
    EXPECT_EQ(material->lobes(), uint32_t(kLobeDiffuseReflection));
    // (0.5, 0.5) has uv (0.75, 0.75): color0; (-0.5, 0.5) has uv (0.25, 0.75): color1.
    const SurfaceInteraction a = hit(*scene, 0.5f, 0.5f);
    EXPECT_EQ(diffuse_reflectance(a), Rgb(0.8f, 0.4f, 0.1f));
    EXPECT_NE(a.hit_bsdf, nullptr);
    EXPECT_EQ(a.bsdf, a.hit_bsdf.get());
    EXPECT_TRUE(a.bsdf->built_for_hit());
    EXPECT_EQ(diffuse_reflectance(hit(*scene, -0.5f, 0.5f)), Rgb(0.1f, 0.3f, 0.6f));
    EXPECT_EQ(diffuse_reflectance(hit(*scene, -0.5f, -0.5f)), Rgb(0.8f, 0.4f, 0.1f));
}

TEST(TexturedMaterial, UntexturedMaterialsStayTheScenesOwnObject) {
    auto scene = plane_with(R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.3"/></bsdf>)");
    const Bsdf* material = scene->shapes()[0]->bsdf;
    EXPECT_FALSE(material->varies());
    SurfaceInteraction si = hit(*scene, 0.5f, 0.5f);
    EXPECT_EQ(si.bsdf, material);  // no per-hit BSDF: the constant fast path
    EXPECT_EQ(si.hit_bsdf, nullptr);
    EXPECT_FALSE(si.bsdf->built_for_hit());
}

TEST(TexturedMaterial, ReusedInteractionDropsThePreviousHitsBsdf) {
    auto scene =
        load_scene_from_string(std::string(R"(<scene version="3.0.0"><sensor type="perspective">
          <float name="fov" value="45"/></sensor>
          <shape type="rectangle"><bsdf type="diffuse">)") +
                                   kChecker + R"(</bsdf></shape>
          <shape type="rectangle"><transform name="to_world"><translate z="-1"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3"/></bsdf></shape></scene>)",
                               ".");
    SurfaceInteraction si;
    ASSERT_TRUE(scene->intersect(Ray(Vec3(0.5f, 0.5f, 1), Vec3(0, 0, -1)), si));
    ASSERT_NE(si.hit_bsdf, nullptr);
    // From below the textured plane only the plain one is hit.
    ASSERT_TRUE(scene->intersect(Ray(Vec3(0.5f, 0.5f, -0.5f), Vec3(0, 0, -1)), si));
    EXPECT_EQ(si.hit_bsdf, nullptr);
    EXPECT_EQ(si.bsdf, scene->shapes()[1]->bsdf);
}

TEST(TexturedMaterial, SurfaceBsdfKeepsTheResolvedBsdfAlive) {
    auto scene = plane_with(std::string("<bsdf type=\"diffuse\">") + kChecker + "</bsdf>");
    std::optional<SurfaceBsdf> kept;
    {
        const SurfaceInteraction si = hit(*scene, 0.5f, 0.5f);
        kept.emplace(*si.bsdf, si.shading, si.geometric_normal, TransportMode::Importance);
    }  // the interaction, the BSDF's other owner, is gone: light vertices outlive it this way
    const Vec3 wo = normalize(Vec3(0.3f, 0.1f, 1)), wi = normalize(Vec3(-0.2f, 0.4f, 1));
    const Rgb f = kept->f(wo, wi);
    // Lambertian (flat shading normal: no correction) with color0: exact up to rounding.
    EXPECT_NEAR(f.r, 0.8f * kInvPi, 1e-6f);
    EXPECT_NEAR(f.g, 0.4f * kInvPi, 1e-6f);
    EXPECT_NEAR(f.b, 0.1f * kInvPi, 1e-6f);
}

TEST(TexturedMaterial, ResolvedDiffuseIsReciprocalAndConservesEnergy) {
    auto scene = plane_with(std::string("<bsdf type=\"diffuse\">") + kChecker + "</bsdf>");
    Rng rng(StreamKey{9, 0, 3, 0});
    for (const Vec2 p : {Vec2(0.5f, 0.5f), Vec2(-0.5f, 0.5f)}) {
        const SurfaceInteraction si = hit(*scene, p.x, p.y);
        const Bsdf& bsdf = *si.bsdf;
        const Rgb albedo_expected = diffuse_reflectance(si);
        const Vec3 wo = normalize(Vec3(0.2f, -0.5f, 0.8f));
        // The sample weights' mean is the directional albedo, which for a Lambertian lobe is the
        // reflectance (every weight equals it: a zero-variance estimator).
        Rgb sum(0.0f);
        const int n = 1000;
        for (int i = 0; i < n; ++i) {
            const std::optional<BsdfSample> s =
                bsdf.sample(wo, rng.next_1d(), rng.next_2d(), TransportMode::Radiance);
            ASSERT_TRUE(s);
            sum += s->weight;
            // f(wo, wi) = f(wi, wo), and pdf's reverse density is the forward one swapped.
            EXPECT_EQ(bsdf.f(wo, s->wi, TransportMode::Radiance),
                      bsdf.f(s->wi, wo, TransportMode::Radiance));
            const BsdfPdf pdf = bsdf.pdf_w(wo, s->wi);
            EXPECT_NEAR(pdf.forward, s->pdf_w.forward, 1e-6f);
            EXPECT_NEAR(pdf.reverse, bsdf.pdf_w(s->wi, wo).forward, 1e-6f);
        }
        const Rgb albedo = sum / float(n);
        EXPECT_NEAR(albedo.r, albedo_expected.r, 1e-5f);
        EXPECT_NEAR(albedo.g, albedo_expected.g, 1e-5f);
        EXPECT_NEAR(albedo.b, albedo_expected.b, 1e-5f);
        EXPECT_LE(albedo.max(), 1.0f);
    }
}

TEST(TexturedMaterial, TopLevelTextureIsSharedThroughRef) {
    const std::string tex = R"(<texture type="checkerboard" id="check">
        <float name="color0" value="0.9"/><float name="color1" value="0.05"/></texture>)";
    auto scene =
        plane_with(R"(<bsdf type="diffuse"><ref name="reflectance" id="check"/></bsdf>)", tex);
    EXPECT_EQ(diffuse_reflectance(hit(*scene, 0.5f, 0.5f)), Rgb(0.9f));
    EXPECT_EQ(diffuse_reflectance(hit(*scene, 0.5f, -0.5f)), Rgb(0.05f));
    // The same texture for a second parameter of another plugin.
    auto plastic = plane_with(R"(<bsdf type="plastic"><ref name="diffuse_reflectance" id="check"/>
        <ref name="specular_reflectance" id="check"/></bsdf>)",
                              tex);
    EXPECT_TRUE(plastic->shapes()[0]->bsdf->varies());
    EXPECT_EQ(hit(*plastic, 0.5f, 0.5f).bsdf->to_string(),
              hit(*plastic, -0.5f, -0.5f).bsdf->to_string());  // both color0 squares
    EXPECT_NE(hit(*plastic, 0.5f, 0.5f).bsdf->to_string(),
              hit(*plastic, 0.5f, -0.5f).bsdf->to_string());
}

TEST(TexturedMaterial, RoughnessAndSpecularReflectanceTakeTextures) {
    const std::string alpha = R"(<texture type="checkerboard" name="alpha">
        <float name="color0" value="0.05"/><float name="color1" value="0.6"/></texture>)";
    for (const std::string type : {"roughconductor", "roughdielectric"}) {
        SCOPED_TRACE(type);
        auto scene = plane_with("<bsdf type=\"" + type + "\">" + alpha + "</bsdf>");
        const std::string smooth = hit(*scene, 0.5f, 0.5f).bsdf->to_string();
        const std::string rough = hit(*scene, 0.5f, -0.5f).bsdf->to_string();
        EXPECT_CONTAINS(smooth, "alpha 0.05,");
        EXPECT_CONTAINS(rough, "alpha 0.6,");
    }
    auto conductor = plane_with(R"(<bsdf type="conductor">
        <texture type="checkerboard" name="specular_reflectance"/></bsdf>)");
    EXPECT_NE(hit(*conductor, 0.5f, 0.5f).bsdf->to_string(),
              hit(*conductor, 0.5f, -0.5f).bsdf->to_string());
}

std::string load_error(const std::string& body);

TEST(TexturedMaterial, RoughPlasticTakesTexturedReflectancesNotAlpha) {
    auto scene = plane_with(R"(<bsdf type="roughplastic">
        <texture type="checkerboard" name="diffuse_reflectance"/>
        <texture type="checkerboard" name="specular_reflectance">
          <float name="color0" value="0.9"/><float name="color1" value="0.3"/></texture>
        </bsdf>)");
    EXPECT_TRUE(scene->shapes()[0]->bsdf->varies());
    EXPECT_CONTAINS(hit(*scene, 0.5f, 0.5f).bsdf->to_string(),
                    "diffuse_reflectance [0.4, 0.4, 0.4], specular_reflectance [0.9, 0.9, 0.9]");
    EXPECT_CONTAINS(hit(*scene, 0.5f, -0.5f).bsdf->to_string(),
                    "diffuse_reflectance [0.2, 0.2, 0.2], specular_reflectance [0.3, 0.3, 0.3]");
    // Mitsuba 3's roughplastic takes a float alpha only (its tables depend on it).
    EXPECT_CONTAINS(load_error("<bsdf type=\"roughplastic\">\n<texture type=\"checkerboard\" "
                               "name=\"alpha\"/></bsdf>"),
                    "<string>:4: bsdf \"roughplastic\", parameter \"alpha\": roughplastic "
                    "takes a float alpha, not a texture (as in Mitsuba 3)");
}

TEST(TexturedMaterial, TwoSidedResolvesItsTexturedSide) {
    auto scene = plane_with(std::string("<bsdf type=\"twosided\"><bsdf type=\"diffuse\">") +
                            kChecker + "</bsdf></bsdf>");
    EXPECT_TRUE(scene->shapes()[0]->bsdf->varies());
    const SurfaceInteraction si = hit(*scene, 0.5f, 0.5f);
    // Both directions below the surface: the front's color0 mirrored.
    const Vec3 wo(0.1f, 0.2f, -0.9f), wi(-0.3f, 0.1f, -0.8f);
    const Rgb f = si.bsdf->f(normalize(wo), normalize(wi), TransportMode::Radiance);
    EXPECT_NEAR(f.r, 0.8f * kInvPi, 1e-6f);
    EXPECT_NEAR(f.b, 0.1f * kInvPi, 1e-6f);
}

std::string load_error(const std::string& body) {
    try {
        load_scene_from_string(
            "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float name=\"fov\" "
            "value=\"45\"/></sensor>\n" +
                body + "</scene>\n",
            ".");
    } catch (const SceneError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no error for:\n" << body;
    return "";
}

TEST(TexturedMaterial, BadTextureInputIsALocatedError) {
    EXPECT_CONTAINS(load_error("<bsdf type=\"diffuse\">\n<texture type=\"wood\" "
                               "name=\"reflectance\"/></bsdf>"),
                    "<string>:4: unknown texture type \"wood\" (supported: bitmap, checkerboard)");
    EXPECT_CONTAINS(load_error("<bsdf type=\"diffuse\">\n<texture type=\"bitmap\" "
                               "name=\"reflectance\">\n<string name=\"filename\" "
                               "value=\"no/such.png\"/></texture></bsdf>"),
                    "<string>:5: texture \"bitmap\", parameter \"filename\": image file not found");
    EXPECT_CONTAINS(load_error("<bsdf type=\"diffuse\">\n<texture type=\"checkerboard\"/></bsdf>"),
                    "<string>:4: a <texture> inside bsdf \"diffuse\" needs name=\"parameter\"");
    EXPECT_CONTAINS(load_error("<texture type=\"checkerboard\" id=\"t\"/>\n<bsdf "
                               "type=\"diffuse\">\n<ref id=\"t\"/></bsdf>"),
                    "<string>:5: <ref id=\"t\">: a texture reference needs name=\"parameter\"");
    EXPECT_CONTAINS(load_error("<bsdf type=\"diffuse\">\n<texture type=\"checkerboard\" "
                               "name=\"reflectance\"><float name=\"color0\" "
                               "value=\"-1\"/></texture></bsdf>"),
                    "a reflectance texture must be finite and non-negative");
    EXPECT_CONTAINS(load_error("<bsdf type=\"diffuse\">\n<texture type=\"checkerboard\" "
                               "name=\"reflectance\"/><texture type=\"checkerboard\" "
                               "name=\"reflectance\"/></bsdf>"),
                    "parameter \"reflectance\" of bsdf \"diffuse\" is given twice");
    // A parameter that takes no texture says so.
    EXPECT_CONTAINS(load_error("<bsdf type=\"phong\">\n<texture type=\"checkerboard\" "
                               "name=\"exponent\"/></bsdf>"),
                    "<string>:4: bsdf \"phong\", parameter \"exponent\": a texture is not "
                    "accepted here");
    // A plugin that has no use for a texture: an unused parameter at its own line.
    EXPECT_CONTAINS(load_error("<emitter type=\"point\">\n<texture type=\"checkerboard\" "
                               "name=\"texture\"/></emitter>"),
                    "<string>:4: unused parameter \"texture\" in emitter \"point\"");
}

}  // namespace
}  // namespace render
