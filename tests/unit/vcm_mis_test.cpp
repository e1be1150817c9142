// The MIS weights of all techniques that can sample one fixed path sum to one.
//
// For explicit paths (camera, a few surface vertices with diffuse, glossy and mirror BSDFs, and
// an area, point, directional or constant light) the test runs the subpath recursions of
// vcm_mis.h along the path from both ends, exactly as the integrator does while tracing, and
// evaluates the weight of every technique that can produce the path: emission hit (s = 0),
// next-event estimation (s = 1), every connection (s, t >= 2), light tracing (t = 1) and every
// merge at a non-specular vertex. For BPT (connections only), BPM (merges only) and VCM (both)
// the weights must sum to one; any wrong density, cosine or distance in the recursion breaks it.

#include "core/integrators/vcm_mis.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "core/camera/perspective_camera.h"
#include "core/lights/area_light.h"
#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/lights/point_light.h"
#include "core/materials/conductor.h"
#include "core/materials/diffuse.h"
#include "core/materials/phong.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/scene/shapes/triangle_mesh.h"

namespace render {
namespace {

enum class LightKind { Area, Point, Directional, Constant };
enum class Material { Diffuse, Glossy, Mirror };

struct PathVertex {
    Vec3 p;
    Vec3 n;
    const Bsdf* bsdf;
    bool specular;
};

// Densities of the light end of a path, as the light reports them (selection probability 1).
struct LightEnd {
    bool delta = false;
    bool finite = true;
    float direct_pdf_a = 0;    // illuminate()'s density of the endpoint (area; solid angle if
                               // infinite)
    float emission_pdf_w = 0;  // emit()'s density of (endpoint, direction)
    float direct_pdf_w = 0;    // illuminate()'s solid-angle density at the first vertex
    float cos_light = 1;
};

class MisSumTest : public ::testing::Test {
  protected:
    static constexpr int kWidth = 64, kHeight = 64;

    MisSumTest()
        : diffuse_(Rgb(0.6f)),
          glossy_(Rgb(0.2f), Rgb(0.6f), 20.0f),
          mirror_(std::nullopt, Rgb(1.0f)),
          rectangle_(make_rectangle_mesh(), Transform::scale(Vec3(0.3f, 0.2f, 1.0f)), false, false,
                     "light") {}

    const Bsdf* bsdf_for(Material m) const {
        switch (m) {
            case Material::Diffuse:
                return &diffuse_;
            case Material::Glossy:
                return &glossy_;
            default:
                return &mirror_;
        }
    }

    // Builds a path from the camera through the given materials to a light of the given kind.
    // Returns false (skip) when a random choice made the geometry degenerate.
    bool build_path(Rng& rng, const std::vector<Material>& materials, LightKind kind) {
        const Vec3 eye(0.1f, -0.2f, -3.0f), target(0, 0, 0);
        camera_ = PerspectiveCamera(Transform::look_at(eye, target, Vec3(0, 1, 0)), 50.0f, 'x',
                                    kWidth, kHeight);
        // Interior vertices are built in eye order and reversed at the end.
        std::vector<PathVertex> eye_order;
        Vec3 position = eye;
        Vec3 direction = camera_
                             .generate_ray(Vec2(rng.next_1d() * kWidth * 0.8f + 6,
                                                rng.next_1d() * kHeight * 0.8f + 6))
                             .direction;
        for (Material m : materials) {
            position = position + direction * (0.7f + rng.next_1d());
            Vec3 n = random_normal_facing(rng, -direction);
            eye_order.push_back(PathVertex{position, n, bsdf_for(m), m == Material::Mirror});
            direction = m == Material::Mirror
                            ? reflect(-direction, n)
                            : Frame::from_normal(n).to_world(random_direction_above(rng, 0.2f));
            if (dot(direction, n) < 0.1f) return false;
        }
        vertices_.assign(eye_order.rbegin(), eye_order.rend());
        kind_ = kind;

        // The light end: `direction` points from the last vertex toward the light.
        const Vec3 first = vertices_.front().p;
        SceneSphere sphere{Vec3(0, 0, 0), 6.0f};
        switch (kind) {
            case LightKind::Area: {
                light_point_ = first + direction * (0.8f + rng.next_1d());
                light_normal_ = random_normal_facing(rng, -direction);
                auto light = std::make_unique<AreaLight>(&rectangle_, Rgb(1.0f));
                LightRadiance le = light->radiance(light_point_, light_normal_, direction);
                const float d2 = length_squared(light_point_ - first);
                end_.delta = false;
                end_.finite = true;
                end_.cos_light = abs_dot(light_normal_, direction);
                end_.direct_pdf_a = le.pdf_direct_a;
                end_.emission_pdf_w = le.pdf_emission_w;
                end_.direct_pdf_w = le.pdf_direct_a * d2 / end_.cos_light;
                light_ = std::move(light);
                break;
            }
            case LightKind::Point: {
                light_point_ = first + direction * (0.8f + rng.next_1d());
                set_delta_light_end(std::make_unique<PointLight>(light_point_, Rgb(1.0f)), first,
                                    true);
                break;
            }
            case LightKind::Directional: {
                auto light = std::make_unique<DirectionalLight>(-direction, Rgb(1.0f));
                light->preprocess(sphere);
                set_delta_light_end(std::move(light), first, false);
                break;
            }
            case LightKind::Constant: {
                auto light = std::make_unique<ConstantLight>(Rgb(1.0f));
                light->preprocess(sphere);
                LightRadiance le = light->radiance(Vec3(), Vec3(), direction);
                end_.delta = false;
                end_.finite = false;
                end_.cos_light = 1;
                end_.direct_pdf_a = le.pdf_direct_a;  // solid angle for infinite lights
                end_.emission_pdf_w = le.pdf_emission_w;
                end_.direct_pdf_w = le.pdf_direct_a;
                light_ = std::move(light);
                break;
            }
        }
        to_light_ = direction;
        return true;
    }

    // The light end of a delta light (point or directional), with the densities it reports.
    void set_delta_light_end(std::unique_ptr<Light> light, const Vec3& first, bool finite) {
        LightIlluminateSample ls;
        EXPECT_TRUE(light->illuminate(first, Vec2(0.5f, 0.5f), ls));
        LightEmitSample es;
        EXPECT_TRUE(light->emit(Vec2(0.3f, 0.3f), Vec2(0.2f, 0.7f), es));
        end_.delta = true;
        end_.finite = finite;
        end_.cos_light = 1;
        end_.direct_pdf_a = es.pdf_direct_a;
        end_.emission_pdf_w = ls.pdf_emission_w;
        end_.direct_pdf_w = ls.pdf_direct_w;
        light_ = std::move(light);
    }

    // Unit direction from vertex i toward its light-side neighbour (the light for i = 0).
    Vec3 toward_light(size_t i) const {
        if (i > 0) return normalize(vertices_[i - 1].p - vertices_[i].p);
        return end_.finite ? normalize(light_point_ - vertices_[0].p) : to_light_;
    }
    // Unit direction from vertex i toward its eye-side neighbour (the camera for the last).
    Vec3 toward_eye(size_t i) const {
        const Vec3 next = i + 1 < vertices_.size() ? vertices_[i + 1].p : camera_.position();
        return normalize(next - vertices_[i].p);
    }
    float distance2_to_light_side(size_t i) const {
        if (i > 0) return length_squared(vertices_[i - 1].p - vertices_[i].p);
        return end_.finite ? length_squared(light_point_ - vertices_[0].p) : 1.0f;
    }
    float distance2_to_eye_side(size_t i) const {
        const Vec3 next = i + 1 < vertices_.size() ? vertices_[i + 1].p : camera_.position();
        return length_squared(next - vertices_[i].p);
    }
    SurfaceBsdf surface(size_t i, TransportMode mode) const {
        const PathVertex& v = vertices_[i];
        return SurfaceBsdf(*v.bsdf, Frame::from_normal(v.n), v.n, mode);
    }
    float camera_pdf_w(const Vec3& dir) const {
        return camera_.direction_pdf(dir) * float(kWidth * kHeight);
    }

    // Sum of the weights of every enabled technique for the current path.
    double weight_sum(const VcmMis& mis, bool use_vc, bool use_vm) const {
        const size_t m = vertices_.size();
        // Light subpath: states after arriving at each vertex (eqs. 31-36).
        std::vector<MisQuantities> light_states(m);
        MisQuantities q =
            mis.start_light(end_.direct_pdf_a, end_.emission_pdf_w, end_.cos_light, end_.delta);
        for (size_t i = 0; i < m; ++i) {
            const Vec3 wo = toward_light(i);
            mis.arrive(q, distance2_to_light_side(i), i > 0 || end_.finite,
                       abs_dot(vertices_[i].n, wo));
            light_states[i] = q;
            if (i + 1 == m) break;
            const Vec3 wi = toward_eye(i);
            const BsdfPdf pdf = surface(i, TransportMode::Importance).pdf(wo, wi);
            mis.scatter(q, abs_dot(vertices_[i].n, wi), pdf.forward, pdf.reverse,
                        vertices_[i].specular);
        }
        // Eye subpath: states after arriving at each vertex, and at the light.
        std::vector<MisQuantities> eye_states(m);
        q = mis.start_camera(camera_pdf_w(-toward_eye(m - 1)));
        for (size_t k = 0; k < m; ++k) {
            const size_t i = m - 1 - k;
            const Vec3 wo = toward_eye(i);
            mis.arrive(q, distance2_to_eye_side(i), true, abs_dot(vertices_[i].n, wo));
            eye_states[i] = q;
            const Vec3 wi = toward_light(i);
            const BsdfPdf pdf = surface(i, TransportMode::Radiance).pdf(wo, wi);
            mis.scatter(q, abs_dot(vertices_[i].n, wi), pdf.forward, pdf.reverse,
                        vertices_[i].specular);
        }
        if (end_.finite) mis.arrive(q, distance2_to_light_side(0), true, end_.cos_light);
        const MisQuantities eye_at_light = q;

        double sum = 0;
        // s = 0: the eye subpath hits the light (eq. 43).
        if (use_vc && !end_.delta)
            sum += mis.weight_emission(eye_at_light, end_.direct_pdf_a, end_.emission_pdf_w);
        // s = 1: next-event estimation from the first vertex (eqs. 44-45).
        if (use_vc && !vertices_[0].specular) {
            const Vec3 wo = toward_eye(0), wi = toward_light(0);
            const BsdfPdf pdf = surface(0, TransportMode::Radiance).pdf(wo, wi);
            sum += mis.weight_direct(eye_states[0], pdf.forward, pdf.reverse, end_.direct_pdf_w,
                                     end_.emission_pdf_w, end_.direct_pdf_w,
                                     abs_dot(vertices_[0].n, wi), end_.cos_light, end_.delta);
        }
        // s >= 2, t >= 2: connect light vertex a to eye vertex a + 1 (eqs. 40-41).
        for (size_t a = 0; use_vc && a + 1 < m; ++a) {
            const size_t b = a + 1;
            if (vertices_[a].specular || vertices_[b].specular) continue;
            const Vec3 d = toward_eye(a);  // from a to b
            const float dist2 = length_squared(vertices_[b].p - vertices_[a].p);
            const BsdfPdf eye_pdf = surface(b, TransportMode::Radiance).pdf(toward_eye(b), -d);
            const BsdfPdf light_pdf = surface(a, TransportMode::Importance).pdf(toward_light(a), d);
            const float eye_pdf_a = eye_pdf.forward * abs_dot(vertices_[a].n, d) / dist2;
            const float light_pdf_a = light_pdf.forward * abs_dot(vertices_[b].n, d) / dist2;
            sum += mis.weight_connection(light_states[a], eye_states[b], eye_pdf_a, light_pdf_a,
                                         light_pdf.reverse, eye_pdf.reverse);
        }
        // t = 1: the last vertex connected to the camera (eq. 46).
        if (use_vc && !vertices_[m - 1].specular) {
            const Vec3 d = toward_eye(m - 1);
            const float dist2 = distance2_to_eye_side(m - 1);
            const BsdfPdf pdf =
                surface(m - 1, TransportMode::Importance).pdf(toward_light(m - 1), d);
            const float camera_pdf_a = camera_pdf_w(-d) * abs_dot(vertices_[m - 1].n, d) / dist2;
            sum += mis.weight_camera(light_states[m - 1], camera_pdf_a, pdf.reverse);
        }
        // Merges at every non-specular vertex (eqs. 38-39).
        for (size_t i = 0; use_vm && i < m; ++i) {
            if (vertices_[i].specular) continue;
            const BsdfPdf pdf =
                surface(i, TransportMode::Radiance).pdf(toward_eye(i), toward_light(i));
            sum += mis.weight_merge(light_states[i], eye_states[i], pdf.forward, pdf.reverse);
        }
        return sum;
    }

    static Vec3 random_direction_above(Rng& rng, float min_cos) {
        Vec3 w = warp::square_to_uniform_hemisphere(rng.next_2d());
        w.z = std::max(w.z, min_cos);
        return normalize(w);
    }
    static Vec3 random_normal_facing(Rng& rng, const Vec3& toward) {
        return Frame::from_normal(toward).to_world(random_direction_above(rng, 0.3f));
    }

    DiffuseBsdf diffuse_;
    PhongBsdf glossy_;
    ConductorBsdf mirror_;
    TriangleMesh rectangle_;
    PerspectiveCamera camera_;
    std::vector<PathVertex> vertices_;  // light order: vertices_[0] is next to the light
    LightKind kind_ = LightKind::Area;
    std::unique_ptr<Light> light_;
    Vec3 light_point_, light_normal_, to_light_;
    LightEnd end_;
};

TEST_F(MisSumTest, WeightsOfAllTechniquesSumToOne) {
    const std::vector<std::vector<Material>> paths = {
        {Material::Diffuse},
        {Material::Diffuse, Material::Diffuse},
        {Material::Glossy, Material::Diffuse, Material::Diffuse},
        {Material::Diffuse, Material::Mirror, Material::Diffuse},
        {Material::Mirror, Material::Diffuse, Material::Glossy},
        {Material::Diffuse, Material::Glossy, Material::Mirror},
        {Material::Glossy, Material::Diffuse, Material::Mirror, Material::Diffuse,
         Material::Glossy},
    };
    const LightKind kinds[] = {LightKind::Area, LightKind::Point, LightKind::Directional,
                               LightKind::Constant};
    Rng rng(StreamKey{2024, 0, 1, 0});
    int checked = 0;
    for (const auto& materials : paths)
        for (LightKind kind : kinds)
            for (int trial = 0; trial < 20; ++trial) {
                if (!build_path(rng, materials, kind)) continue;
                for (int power : {1, 2}) {
                    const double eta = kPi * 0.02 * 0.02 * kWidth * kHeight;
                    SCOPED_TRACE(::testing::Message()
                                 << "path of " << materials.size() << " vertices, light kind "
                                 << int(kind) << ", trial " << trial << ", power " << power);
                    // A path with no non-specular vertex cannot be merged; one whose only
                    // non-specular ends are delta cannot be connected: skip those families.
                    bool has_diffuse = false;
                    for (const PathVertex& v : vertices_) has_diffuse |= !v.specular;
                    const double bpt =
                        weight_sum(VcmMis(power, true, false, eta, kWidth * kHeight), true, false);
                    const double vcm =
                        weight_sum(VcmMis(power, true, true, eta, kWidth * kHeight), true, true);
                    const double bpm =
                        weight_sum(VcmMis(power, false, true, eta, kWidth * kHeight), false, true);
                    // float arithmetic over a handful of terms: 1e-4 relative.
                    if (bpt > 0) {
                        EXPECT_NEAR(bpt, 1.0, 1e-4) << "BPT";
                    }
                    if (has_diffuse) {
                        EXPECT_NEAR(vcm, 1.0, 1e-4) << "VCM";
                        EXPECT_NEAR(bpm, 1.0, 1e-4) << "BPM";
                    }
                    ++checked;
                }
            }
    EXPECT_GT(checked, 300);
}

// The test must be able to fail: dropping one technique breaks the sum.
TEST_F(MisSumTest, DetectsAMissingTechnique) {
    Rng rng(StreamKey{7, 0, 1, 0});
    ASSERT_TRUE(build_path(rng, {Material::Diffuse, Material::Diffuse}, LightKind::Area));
    const double eta = kPi * 0.02 * 0.02 * kWidth * kHeight;
    const VcmMis bpt_mis(2, true, false, eta, kWidth * kHeight);
    const double full = weight_sum(bpt_mis, true, false);
    EXPECT_NEAR(full, 1.0, 1e-4);
    // Merging weights alone (with connections' weights computed as if merging were on) must
    // not sum to one.
    const double merges_only =
        weight_sum(VcmMis(2, true, true, eta, kWidth * kHeight), false, true);
    EXPECT_LT(merges_only, 0.999);
}

}  // namespace
}  // namespace render
