#include <gtest/gtest.h>

#include "core/base/ray_transform_check.h"
#include "core/base/scene_limits.h"
#include "core/math/frame.h"
#include "core/math/transform.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

void expect_vec_near(const Vec3& a, const Vec3& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

TEST(Transform, ComposesRightToLeft) {
    // (T * S) applies S first: scale 2 then translate by (1, 0, 0).
    Transform t = Transform::translate(Vec3(1, 0, 0)) * Transform::scale(Vec3(2, 2, 2));
    expect_vec_near(t.apply_point(Vec3(1, 1, 1)), Vec3(3, 2, 2), 1e-6f);
    expect_vec_near(t.apply_vector(Vec3(1, 1, 1)), Vec3(2, 2, 2), 1e-6f);
}

TEST(Transform, InverseRoundTrips) {
    Transform t = Transform::translate(Vec3(1, -2, 3)) * Transform::rotate(Vec3(1, 1, 0), 33.0f) *
                  Transform::scale(Vec3(2, 0.5f, 3));
    Transform inv = t.inverse();
    Vec3 p(0.3f, -0.7f, 1.9f);
    expect_vec_near(inv.apply_point(t.apply_point(p)), p, 1e-5f);
    EXPECT_FALSE(t.is_singular());
    EXPECT_TRUE(Transform::scale(Vec3(1, 0, 1)).is_singular());
}

TEST(Transform, RaysPassOnlyThroughWellConditionedTransforms) {
    // What the shipped scenes use: rotations, mirrors, uniform and moderately flattening scales.
    for (const Transform& t :
         {Transform(), Transform::scale(Vec3(-1, 1, 1)), Transform::scale(Vec3(1e-4f)),
          Transform::scale(Vec3(1e6f)), Transform::scale(Vec3(10, 0.01f, 10)),
          Transform::translate(Vec3(1e9f, 0, 0)) * Transform::rotate(Vec3(1, 2, 3), 77.0f) *
              Transform::scale(Vec3(1, 0.3f, 0.6f))})
        EXPECT_EQ(ray_transform_problem(t), "");
    // The input that aborted the process in Embree: a mirror flattened to 1e-30 in z.
    EXPECT_NE(ray_transform_problem(Transform::scale(Vec3(-1, 1, 1e-30f))).find("near-singular"),
              std::string::npos);
    EXPECT_NE(ray_transform_problem(Transform::scale(Vec3(1, 1, 1e-7f))).find("near-singular"),
              std::string::npos);
    EXPECT_NE(ray_transform_problem(Transform::scale(Vec3(1, 0, 1))).find("singular"),
              std::string::npos);
    Transform::Matrix m = Transform().matrix();
    m[1][2] = std::nan("");
    EXPECT_EQ(ray_transform_problem(Transform(m)), "the transform is not finite");
    m[1][2] = INFINITY;
    EXPECT_EQ(ray_transform_problem(Transform(m)), "the transform is not finite");
    // Well conditioned but so small that a point within the scene limits lands beyond what
    // Embree accepts in the shape's space.
    EXPECT_NE(ray_transform_problem(Transform::scale(Vec3(1e-7f))).find("shrinks too much"),
              std::string::npos);
    // Rotations and mirrors are as well conditioned as can be: ||A||_F ||A^-1||_F = 3.
    const Transform r = Transform::rotate(Vec3(0, 1, 1), 45.0f) * Transform::scale(Vec3(-1, 1, 1));
    double n = 0, ni = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            n += r.matrix()[i][j] * r.matrix()[i][j];
            ni += r.inverse().matrix()[i][j] * r.inverse().matrix()[i][j];
        }
    EXPECT_NEAR(std::sqrt(n * ni), 3.0, 1e-9);
}

TEST(Transform, NormalsStayPerpendicular) {
    Transform t = Transform::rotate(Vec3(0, 0, 1), 20.0f) * Transform::scale(Vec3(1, 4, 0.5f));
    Vec3 tangent(1, -1, 0), normal(1, 1, 0);  // perpendicular in object space
    Vec3 tt = t.apply_vector(tangent), tn = t.apply_normal(normal);
    EXPECT_NEAR(dot(tt, tn), 0.0f, 1e-5f);
}

TEST(Transform, RotateIsRightHanded) {
    expect_vec_near(Transform::rotate(Vec3(0, 0, 1), 90).apply_vector(Vec3(1, 0, 0)), Vec3(0, 1, 0),
                    1e-6f);
}

TEST(Transform, LookAtMatchesMitsuba) {
    // Mitsuba's lookat: +z toward the target, +y up, +x = up x forward (left in the image).
    Transform t = Transform::look_at(Vec3(0, 0, 5), Vec3(0, 0, 0), Vec3(0, 1, 0));
    expect_vec_near(t.apply_point(Vec3(0, 0, 0)), Vec3(0, 0, 5), 1e-6f);
    expect_vec_near(t.apply_vector(Vec3(0, 0, 1)), Vec3(0, 0, -1), 1e-6f);
    expect_vec_near(t.apply_vector(Vec3(0, 1, 0)), Vec3(0, 1, 0), 1e-6f);
    expect_vec_near(t.apply_vector(Vec3(1, 0, 0)), Vec3(-1, 0, 0), 1e-6f);
}

TEST(Frame, IsOrthonormalForAllNormals) {
    Rng rng(StreamKey{11, 0, 1, 0});
    for (int i = 0; i < 10000; ++i) {
        Vec3 n = warp::square_to_uniform_sphere(rng.next_2d());
        if (i == 0) n = Vec3(0, 0, -1);  // the branch point of the construction
        Frame f = Frame::from_normal(n);
        EXPECT_NEAR(dot(f.s, f.t), 0.0f, 1e-5f);
        EXPECT_NEAR(dot(f.s, f.n), 0.0f, 1e-5f);
        EXPECT_NEAR(length(f.s), 1.0f, 1e-5f);
        EXPECT_NEAR(length(f.t), 1.0f, 1e-5f);
        expect_vec_near(cross(f.s, f.t), n, 1e-5f);
        Vec3 w = warp::square_to_uniform_sphere(rng.next_2d());
        expect_vec_near(f.to_world(f.to_local(w)), w, 1e-5f);
    }
}

TEST(Rng, StreamsDependOnlyOnTheirKey) {
    Rng a(StreamKey{1, 2, 3, 4}), b(StreamKey{1, 2, 3, 4}), c(StreamKey{1, 2, 3, 5});
    bool all_equal_c = true;
    for (int i = 0; i < 100; ++i) {
        uint32_t va = a.next_u32(), vb = b.next_u32(), vc = c.next_u32();
        EXPECT_EQ(va, vb);
        all_equal_c &= va == vc;
    }
    EXPECT_FALSE(all_equal_c);
}

TEST(Rng, UniformMeanAndRange) {
    // Mean of 1e6 uniforms: standard error 1/sqrt(12e6) = 2.9e-4; tolerance 5 standard errors.
    Rng rng(StreamKey{5, 0, 1, 9});
    double sum = 0;
    for (int i = 0; i < 1000000; ++i) {
        float u = rng.next_1d();
        ASSERT_GE(u, 0.0f);
        ASSERT_LT(u, 1.0f);
        sum += u;
    }
    EXPECT_NEAR(sum / 1e6, 0.5, 5 * 2.9e-4);
}

}  // namespace
}  // namespace render
