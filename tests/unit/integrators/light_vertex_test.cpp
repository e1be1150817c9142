// LightVertex (core/integrators/bidirectional/subpath.h): a stored light vertex answers every
// question a connection or a merge asks of it exactly as the Vertex it was built from, at a
// surface (its BSDF) and in a medium (its medium part, which shares the BSDF's bytes), and keeps
// doing so through copies, moves and assignments between the two kinds.

#include <gtest/gtest.h>

#include <memory>
#include <utility>
#include <vector>

#include "core/integrators/bidirectional/subpath.h"
#include "core/materials/diffuse.h"
#include "core/media/henyey_greenstein.h"
#include "core/media/homogeneous_medium.h"

namespace render::bidirectional {
namespace {

const Vec3 kWo = normalize(Vec3(0.3f, 0.2f, 0.9f));
const Vec3 kWi = normalize(Vec3(-0.5f, 0.1f, 0.7f));

struct Fixture {
    DiffuseBsdf bsdf{Rgb(0.2f, 0.5f, 0.8f)};
    HomogeneousMedium medium{Rgb(0.1f), Rgb(0.3f, 0.4f, 0.5f),
                             std::make_shared<HenyeyGreenstein>(0.6f)};
    Vertex surface, volume;

    Fixture() {
        surface.p = Vec3(1, 2, 3);
        surface.n = normalize(Vec3(0.1f, 0.0f, 1.0f));
        const Frame shading = Frame::from_normal(normalize(Vec3(0.0f, 0.2f, 1.0f)));
        surface.bsdf.emplace(bsdf, shading, surface.n, TransportMode::Importance);
        volume.p = Vec3(-1, 0.5f, 2);
        volume.medium = &medium;
        volume.phase = &medium.phase();
        volume.previous = Vec3(4, 5, 6);
        volume.arrival_distance = 0.7f;
        volume.sigma_t = 0.4f;
        volume.photon_beam = 0.25f;
    }
};

LightVertex stored(const Vertex& v, int path_length) {
    return LightVertex(v, kWo, Rgb(0.5f, 1.0f, 2.0f), path_length, MisQuantities{1, 2, 3}, false);
}

void expect_same_surface(const LightVertex& lv, const Vertex& v) {
    EXPECT_FALSE(lv.in_medium());
    EXPECT_EQ(lv.medium(), nullptr);
    EXPECT_EQ(lv.phase(), nullptr);
    EXPECT_EQ(lv.p.x, v.p.x);
    EXPECT_EQ(lv.n().x, v.n.x);
    EXPECT_EQ(lv.n().z, v.n.z);
    EXPECT_EQ(lv.cos(kWi), v.cos(kWi));
    EXPECT_EQ(lv.shading_cos(kWi), v.shading_cos(kWi));
    const BsdfEvaluation a = lv.evaluate(kWo, kWi), b = v.evaluate(kWo, kWi);
    EXPECT_EQ(a.f.g, b.f.g);
    EXPECT_EQ(a.pdf_w.forward, b.pdf_w.forward);
    EXPECT_EQ(a.pdf_w.reverse, b.pdf_w.reverse);
    EXPECT_EQ(lv.f(kWo, kWi).b, v.f(kWo, kWi).b);
    EXPECT_GT(a.f.g, 0.0f);  // the directions are ones the BSDF reflects: a real comparison
    ASSERT_TRUE(lv.bsdf().has_value());
    EXPECT_EQ(&lv.bsdf()->bsdf(), &v.bsdf->bsdf());
    EXPECT_EQ(lv.photon_beam(), 0.0f);
}

void expect_same_medium(const LightVertex& lv, const Vertex& v) {
    EXPECT_TRUE(lv.in_medium());
    EXPECT_EQ(lv.medium(), v.medium);
    EXPECT_EQ(lv.phase(), v.phase);
    EXPECT_EQ(lv.p.y, v.p.y);
    EXPECT_EQ(lv.n().x, 0.0f);
    EXPECT_EQ(lv.cos(kWi), 1.0f);
    EXPECT_EQ(lv.shading_cos(kWi), 1.0f);
    const BsdfEvaluation a = lv.evaluate(kWo, kWi), b = v.evaluate(kWo, kWi);
    EXPECT_EQ(a.f.r, b.f.r);
    EXPECT_EQ(a.pdf_w.forward, b.pdf_w.forward);
    EXPECT_EQ(lv.previous().z, v.previous.z);
    EXPECT_EQ(lv.arrival_distance(), v.arrival_distance);
    EXPECT_EQ(lv.sigma_t(), v.sigma_t);
    EXPECT_EQ(lv.photon_beam(), v.photon_beam);
    EXPECT_FALSE(lv.bsdf().has_value());
}

TEST(LightVertex, IsTwoCacheLines) {
    EXPECT_EQ(sizeof(LightVertex), 128u);
    EXPECT_EQ(alignof(LightVertex), 64u);
}

TEST(LightVertex, AnswersAsItsVertexAtASurfaceAndInAMedium) {
    const Fixture f;
    const LightVertex s = stored(f.surface, 3), m = stored(f.volume, 4);
    expect_same_surface(s, f.surface);
    expect_same_medium(m, f.volume);
    EXPECT_EQ(s.path_length, 3);
    EXPECT_EQ(m.path_length, 4);
    EXPECT_EQ(s.wo.z, kWo.z);
    EXPECT_EQ(s.throughput.b, 2.0f);
    EXPECT_EQ(m.mis.dVM, 3.0f);
    EXPECT_FALSE(m.finite_light);
}

TEST(LightVertex, CopiesMovesAndAssignmentsAcrossKindsKeepEverything) {
    const Fixture f;
    std::vector<LightVertex> vertices;
    for (int i = 0; i < 40; ++i) vertices.push_back(stored(i % 3 ? f.surface : f.volume, i));
    // Growing the vector moved every vertex at least once.
    for (int i = 0; i < 40; ++i) {
        EXPECT_EQ(vertices[i].path_length, i);
        if (i % 3)
            expect_same_surface(vertices[i], f.surface);
        else
            expect_same_medium(vertices[i], f.volume);
    }
    LightVertex a = vertices[0];  // medium
    a = vertices[1];              // surface over medium
    expect_same_surface(a, f.surface);
    a = vertices[3];  // medium over surface
    expect_same_medium(a, f.volume);
    LightVertex b = std::move(vertices[2]);
    expect_same_surface(b, f.surface);
    b = std::move(a);
    expect_same_medium(b, f.volume);
    b = b;  // self-assignment keeps it
    expect_same_medium(b, f.volume);
}

}  // namespace
}  // namespace render::bidirectional
