// Importance sampling of textured area lights on meshes (core/lights/textured_mesh_emission.h).
//
// - The sampler against its pdf: a chi-square test over the sampler's cells (each triangle's
//   K x K sub-triangles) of 1e6 samples, with each cell's expected probability the pdf the
//   light reports at the cell's centroid (find()) times the cell's area computed here from the
//   geometry; those probabilities sum to one (1e-4), and a midpoint sum of the pdf over a fine
//   grid of the emitter integrates to one (2e-3: cells cut by the grid's squares).
// - pdf matches sample: the pdf_area a sample reports is the one found back from its point,
//   exactly (but at cell edges, where rounding may pick the neighbour: fewer than 1 in 1000);
//   illuminate()'s pdf_direct_w and emit()'s pdf_direct_a equal what radiance() reports for a
//   ray hitting that point (the MIS densities of the integrators), to float rounding (1e-5).
// - The image equals uniform sampling's: a floor lit by a textured rectangle, rendered with
//   both, agrees in every 8 x 8 block to 5 combined standard errors (block test), and the test
//   can see a 5 % difference.
// - Meshes of more than 64 triangles take a radiance texture: hits see the texture at their uv.

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/lights/area_light.h"
#include "core/lights/textured_mesh_emission.h"
#include "core/render/render_options.h"
#include "core/sampling/rng.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "core/shapes/triangle_mesh.h"
#include "tests/support/block_estimate.h"
#include "tests/support/chi_square.h"

namespace render {
namespace {

testing::ChiSquareFamily family;

// A bright spot on a dim background, grey: L = 0.05 + 4 exp(-|uv - (0.3, 0.7)|^2 / 0.02).
class SpotTexture final : public Texture {
  public:
    Rgb eval(Vec2 uv) const override {
        const float dx = uv.x - 0.3f, dy = uv.y - 0.7f;
        return Rgb(0.05f + 4.0f * std::exp(-(dx * dx + dy * dy) / 0.02f));
    }
    Rgb mean() const override { return Rgb(0.3f); }
    float min_value() const override { return 0.05f; }
    float max_value() const override { return 4.05f; }
    std::string to_string() const override { return "spot"; }
};

// [-1, 1]^2 at z = 0 in n x n quads (2 n^2 triangles), facing +z, uv = ((x + 1) / 2, (y + 1) / 2).
TriangleMesh grid_mesh(int n) {
    MeshData m;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) {
            m.positions.push_back(Vec3(-1 + 2.0f * x / n, -1 + 2.0f * y / n, 0));
            m.uvs.push_back(Vec2(float(x) / n, float(y) / n));
        }
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const uint32_t a = uint32_t(y * (n + 1) + x), b = a + 1, c = a + uint32_t(n + 1),
                           d = c + 1;
            m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
        }
    return TriangleMesh(std::move(m), Transform(), false, false, "grid");
}

CHI_SQUARE_TEST(family, TexturedMeshEmission, SamplerMatchesItsPdf, 1) {
    const TriangleMesh mesh = grid_mesh(10);
    const SpotTexture texture;
    const TexturedMeshEmission emission(mesh, texture);
    const int k = emission.subdivision();
    EXPECT_EQ(k, 16);  // 200 triangles: 2^17 / 400 -> the cap of 16
    const size_t slots = 2 * size_t(k) * size_t(k);
    std::vector<double> probability(mesh.triangle_count() * slots, 0.0);
    double total = 0;
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
        const uint32_t* i = &mesh.indices()[3 * t];
        const Vec3 p0 = mesh.positions()[i[0]], e1 = mesh.positions()[i[1]] - p0,
                   e2 = mesh.positions()[i[2]] - p0;
        const double cell_area = 0.5 * length(cross(e1, e2)) / (k * k);
        for (int a = 0; a < k; ++a)
            for (int b = 0; a + b < k; ++b)
                for (int d = 0; d < 2 && a + b + d < k; ++d) {
                    // The cell's centroid in barycentrics.
                    const float b1 = (d == 0 ? a + 1.0f / 3 : a + 2.0f / 3) / k;
                    const float b2 = (d == 0 ? b + 1.0f / 3 : b + 2.0f / 3) / k;
                    Vec2 uv;
                    float pdf;
                    size_t cell;
                    ASSERT_TRUE(emission.find(p0 + e1 * b1 + e2 * b2, uv, pdf, &cell));
                    ASSERT_EQ(cell, t * slots + size_t(2 * (a * k + b) + d));
                    probability[cell] = pdf * cell_area;
                    total += probability[cell];
                }
    }
    EXPECT_NEAR(total, 1.0, 1e-4);
    const int n = 1000000;
    std::vector<double> observed(probability.size(), 0.0);
    Rng rng(StreamKey{21, 0, 1, 0});
    int mismatched = 0, lost = 0;
    for (int s = 0; s < n; ++s) {
        const ShapeSample sample = emission.sample(rng.next_2d());
        Vec2 uv;
        float pdf;
        size_t cell;
        if (!emission.find(sample.p, uv, pdf, &cell)) {
            ++lost;
            continue;
        }
        observed[cell] += 1;
        mismatched += pdf != sample.pdf_area;
        EXPECT_EQ(sample.n.z, 1.0f);
    }
    EXPECT_EQ(lost, 0);
    EXPECT_LT(mismatched, n / 1000);
    const testing::ChiSquareResult r =
        testing::chi_square_test_discrete(family, observed, probability, n);
    EXPECT_TRUE(r.passed) << r.message;
}

TEST(TexturedMeshEmission, PdfIntegratesToOne) {
    const TriangleMesh mesh = grid_mesh(7);
    const SpotTexture texture;
    const TexturedMeshEmission emission(mesh, texture);
    const int m = 1500;
    double sum = 0;
    for (int y = 0; y < m; ++y)
        for (int x = 0; x < m; ++x) {
            Vec2 uv;
            float pdf;
            ASSERT_TRUE(
                emission.find(Vec3(-1 + 2 * (x + 0.5f) / m, -1 + 2 * (y + 0.5f) / m, 0), uv, pdf));
            sum += pdf;
        }
    EXPECT_NEAR(sum * 4.0 / (double(m) * m), 1.0, 2e-3);
}

// Long thin triangles, each spanning the whole mesh along x: the locator's grid coarsens so that
// its lists stay within 16 entries a triangle, and still finds every point.
TEST(TexturedMeshEmission, ThinTrianglesKeepTheLocatorSmall) {
    MeshData m;
    const int n = 2000;
    for (int i = 0; i <= n; ++i) {
        const float y = -1 + 2.0f * i / n;
        m.positions.push_back(Vec3(-1, y, 0));
        m.positions.push_back(Vec3(1, y, 0));
        m.uvs.push_back(Vec2(0, float(i) / n));
        m.uvs.push_back(Vec2(1, float(i) / n));
    }
    for (uint32_t i = 0; i < uint32_t(n); ++i)
        m.indices.insert(m.indices.end(),
                         {2 * i, 2 * i + 1, 2 * i + 3, 2 * i, 2 * i + 3, 2 * i + 2});
    const TriangleMesh mesh(std::move(m), Transform(), false, false, "stripes");
    const TexturedMeshEmission emission(mesh, SpotTexture());
    EXPECT_LE(emission.locator_entries(), 16 * mesh.triangle_count() + 4096);
    Rng rng(StreamKey{23, 0, 1, 0});
    for (int i = 0; i < 2000; ++i) {
        const Vec2 u = rng.next_2d();
        const Vec3 p(-1 + 2 * u.x, -1 + 2 * u.y, 0);
        Vec2 uv;
        float pdf;
        ASSERT_TRUE(emission.find(p, uv, pdf)) << p;
        EXPECT_NEAR(uv.x, 0.5f * (p.x + 1), 1e-4f);
        EXPECT_NEAR(uv.y, 0.5f * (p.y + 1), 1e-4f);
        EXPECT_GT(pdf, 0.0f);
    }
}

TEST(TexturedMeshEmission, AreaLightPdfsMatchItsSamples) {
    const TriangleMesh mesh = grid_mesh(10);
    const AreaLight light(&mesh, RgbParam{Rgb(), std::make_shared<SpotTexture>()});
    ASSERT_NE(light.textured_mesh(), nullptr);
    Rng rng(StreamKey{22, 0, 1, 0});
    const Vec3 receiver(0.3f, -0.2f, 1.5f);
    int checked = 0, mismatched = 0;
    for (int i = 0; i < 20000; ++i) {
        LightIlluminateSample ls;
        ASSERT_TRUE(light.illuminate(receiver, rng.next_2d(), ls));
        const Vec3 q = receiver + ls.wi * ls.distance;
        const LightRadiance le = light.radiance(q, Vec3(0, 0, 1), ls.wi);
        const float want = le.pdf_direct_a * ls.distance * ls.distance / ls.cos_at_light;
        ++checked;
        if (std::abs(ls.pdf_direct_w - want) > 1e-5f * want) {
            ++mismatched;
            continue;
        }
        EXPECT_NEAR(ls.pdf_emission_w, le.pdf_emission_w, 1e-5f * le.pdf_emission_w);
        // The point recomputed from receiver + wi d moves uv by float rounding: 1e-4.
        EXPECT_NEAR(ls.radiance.r, le.radiance.r, 1e-4f * le.radiance.r);
        LightEmitSample es;
        ASSERT_TRUE(light.emit(rng.next_2d(), rng.next_2d(), es));
        const LightRadiance at_origin = light.radiance(es.origin, Vec3(0, 0, 1), -es.direction);
        ++checked;
        if (es.pdf_direct_a != at_origin.pdf_direct_a) {
            ++mismatched;
            continue;
        }
        EXPECT_NEAR(es.pdf_emission_w, at_origin.pdf_emission_w, 1e-5f * es.pdf_emission_w);
    }
    std::cout << mismatched << " of " << checked << " at cell edges\n";
    EXPECT_LT(mismatched, checked / 1000);
}

// A hit on the textured light finds its density and uv from its own triangle and barycentrics
// (radiance_at: SurfaceInteraction::prim_id, prim_uv), as radiance() finds them through the
// locator from the point: the same cell's density (but at cell edges, where the two may round
// to neighbours: fewer than 1 in 1000) and the same radiance to float rounding of uv (1e-4).
TEST(TexturedMeshEmission, AHitFindsItsDensityWithoutTheLocator) {
    auto owned = std::make_unique<TriangleMesh>(grid_mesh(10));
    const TriangleMesh* mesh = owned.get();
    Scene scene;
    scene.set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    scene.add_shape(std::move(owned), nullptr);
    scene.commit();
    const AreaLight light(mesh, RgbParam{Rgb(), std::make_shared<SpotTexture>()});
    ASSERT_NE(light.textured_mesh(), nullptr);
    Rng rng(StreamKey{23, 0, 1, 0});
    int checked = 0, mismatched = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec2 u = rng.next_2d();
        const Vec3 target(-1 + 2 * u.x, -1 + 2 * u.y, 0);
        const Vec3 origin(0.2f, -0.1f, 1.5f);
        SurfaceInteraction si;
        ASSERT_TRUE(scene.intersect(Ray(origin, normalize(target - origin)), si));
        const Vec3 d = normalize(target - origin);
        const LightRadiance at_hit = light.radiance_at(si, d);
        const LightRadiance at_point = light.radiance(si.p, si.geometric_normal, d);
        ASSERT_GT(at_point.pdf_direct_a, 0);
        ++checked;
        if (at_hit.pdf_direct_a != at_point.pdf_direct_a) {
            ++mismatched;
            continue;
        }
        EXPECT_EQ(at_hit.pdf_emission_w, at_point.pdf_emission_w);
        EXPECT_NEAR(at_hit.radiance.r, at_point.radiance.r, 1e-4f * at_point.radiance.r);
    }
    EXPECT_LT(mismatched, checked / 1000);
}

// A floor lit from above by a rectangle emitting a checkerboard (4 x 4 squares of 20 and 0.2).
std::string lit_floor(bool uniform) {
    return std::string(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="0, 3, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"/></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.8"/><rotate x="1" angle="90"/><translate y="1.5"/></transform>
    <emitter type="area">
      <texture type="checkerboard" name="radiance"><rgb name="color0" value="20, 10, 5"/>
        <rgb name="color1" value="0.2"/><transform name="to_uv"><scale value="4"/></transform></texture>
      <boolean name="uniform_sampling" value=")") +
           (uniform ? "true" : "false") + R"("/>
    </emitter></shape>
</scene>)";
}

TEST(TexturedMeshEmission, ImageEqualsUniformSamplings) {
    auto sampled = load_scene_from_string(lit_floor(false), ".");
    auto uniform = load_scene_from_string(lit_floor(true), ".");
    const auto* a_light = dynamic_cast<const AreaLight*>(sampled->lights()[0].get());
    const auto* b_light = dynamic_cast<const AreaLight*>(uniform->lights()[0].get());
    ASSERT_TRUE(a_light && b_light);
    ASSERT_NE(a_light->textured_mesh(), nullptr);
    ASSERT_EQ(b_light->textured_mesh(), nullptr);
    RenderSettings settings = resolve_render_settings("pt", {}, sampled->settings);
    settings.seed = 41;
    const testing::BlockEstimate a = testing::render_block_estimate(*sampled, settings, 16, 8, 4);
    settings.seed = 43;
    const testing::BlockEstimate b = testing::render_block_estimate(*uniform, settings, 16, 8, 4);
    const std::vector<std::string> differ = testing::differing_blocks(a, b, 1.0, 5.0, 1e-6);
    EXPECT_TRUE(differ.empty()) << differ.size() << " block values differ, first: " << differ[0];
    EXPECT_FALSE(testing::differing_blocks(a, b, 1.05, 5.0, 1e-6).empty());
    double se_a = 0, se_b = 0;
    for (size_t i = 0; i < a.standard_error.size(); ++i)
        se_a += a.standard_error[i], se_b += b.standard_error[i];
    std::cout << "mean standard error: importance sampled " << se_a / a.standard_error.size()
              << ", uniform " << se_b / b.standard_error.size() << "\n";
}

TEST(TexturedMeshEmission, LargeMeshesTakeARadianceTexture) {
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("textured_mesh_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    {
        // A strip of 100 triangles along x, uv = (x / 50, y).
        std::ofstream obj(dir / "strip.obj");
        for (int i = 0; i <= 50; ++i)
            obj << "v " << i << " 0 0\nv " << i << " 1 0\nvt " << i / 50.0 << " 0\nvt " << i / 50.0
                << " 1\n";
        for (int i = 0; i < 50; ++i) {
            const int a = 2 * i + 1, b = 2 * i + 2, c = 2 * i + 3, d = 2 * i + 4;
            obj << "f " << a << "/" << a << " " << c << "/" << c << " " << d << "/" << d << "\nf "
                << a << "/" << a << " " << d << "/" << d << " " << b << "/" << b << "\n";
        }
    }
    auto scene = load_scene_from_string(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="45"/></sensor>
  <shape type="obj"><string name="filename" value="strip.obj"/>
    <emitter type="area"><texture type="checkerboard" name="radiance">
      <rgb name="color0" value="3"/><rgb name="color1" value="1"/>
      <transform name="to_uv"><scale x="10" y="1"/></transform></texture></emitter></shape></scene>)",
                                        dir);
    std::filesystem::remove_all(dir);
    const Light& light = *scene->lights()[0];
    int checked = 0;
    for (int i = 0; i < 400; ++i) {
        const float x = 0.0625f + i * 0.1243f, y = 0.37f + 0.0011f * i;
        SurfaceInteraction si;
        const Ray down(Vec3(x, y, 1), Vec3(0, 0, -1));
        ASSERT_TRUE(scene->intersect(down, si)) << x;
        // Mitsuba's checkerboard: color0 where the fractional parts of 10 u and v are on the same
        // side of 1/2; obj uv are flipped in v by default (flip_tex_coords), so v = 1 - y.
        const float fu = 10 * x / 50 - std::floor(10 * x / 50), fv = 1 - y;
        if (std::abs(fu - 0.5f) < 1e-3f || fu < 1e-3f) continue;
        const float want = (fu > 0.5f) == (fv > 0.5f) ? 3.0f : 1.0f;
        EXPECT_EQ(light.radiance(si.p, si.geometric_normal, down.direction).radiance.r, want)
            << x << ", " << y;
        ++checked;
    }
    EXPECT_GT(checked, 390);
}

// pbrt-v4's image area light ("string filename") is the Mitsuba area emitter with a bitmap
// radiance (clamped at the edges, as pbrt's): a pbrt quad and a Mitsuba rectangle with the same
// uv emit the same radiance at the same points; "L" with "filename" and a scale are refused at
// their line.
TEST(TexturedMeshEmission, PbrtImageAreaLightsMatchMitsubas) {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests";
    auto mitsuba = load_scene_from_string(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>"
        "<shape type=\"rectangle\"><emitter type=\"area\">"
        "<texture type=\"bitmap\" name=\"radiance\"><string name=\"filename\" "
        "value=\"textures/tiles.png\"/><string name=\"wrap_mode\" value=\"clamp\"/>"
        "</texture></emitter></shape></scene>",
        dir);
    const std::string quad =
        "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]\n"
        "  \"integer indices\" [0 1 2 0 2 3] \"point2 uv\" [0 1 1 1 1 0 0 0]\n";
    auto pbrt = pbrt::load_scene_from_string(
        "Camera \"perspective\"\nWorldBegin\n"
        "AreaLightSource \"diffuse\" \"string filename\" \"textures/tiles.png\"\n" +
            quad,
        dir);
    std::set<float> values;
    for (int i = 0; i < 100; ++i) {
        const Ray down(Vec3(-0.95f + 0.019f * i, 0.37f - 0.013f * i, 2), Vec3(0, 0, -1));
        SurfaceInteraction a, b;
        ASSERT_TRUE(mitsuba->intersect(down, a));
        ASSERT_TRUE(pbrt->intersect(down, b));
        ASSERT_TRUE(a.emitter && b.emitter);
        const Rgb la = a.emitter->radiance(a.p, a.geometric_normal, down.direction).radiance;
        const Rgb lb = b.emitter->radiance(b.p, b.geometric_normal, down.direction).radiance;
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(la[c], lb[c], 1e-5f) << i;
        values.insert(la.r);
    }
    EXPECT_GT(values.size(), 3u);  // tiles.png is no constant
    auto error = [&](const std::string& light) {
        try {
            pbrt::load_scene_from_string("Camera \"perspective\"\nWorldBegin\n" + light + quad,
                                         dir);
        } catch (const SceneError& e) {
            return std::string(e.what());
        }
        return std::string("loaded");
    };
    const std::string both = error(
        "AreaLightSource \"diffuse\" \"string filename\" \"textures/tiles.png\" \"rgb L\" [1 1 "
        "1]\n");
    EXPECT_NE(both.find(":3"), std::string::npos) << both;
    EXPECT_NE(both.find("not both"), std::string::npos) << both;
    const std::string scaled = error(
        "AreaLightSource \"diffuse\" \"string filename\" \"textures/tiles.png\" \"float scale\" "
        "[2]\n");
    EXPECT_NE(scaled.find("a scaled image area light"), std::string::npos) << scaled;
}

}  // namespace
}  // namespace render
