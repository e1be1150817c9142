#include "bench/procedural_mesh.h"

#include <cmath>

#include "core/lights/point_light.h"
#include "core/materials/diffuse.h"
#include "core/math/constants.h"
#include "core/math/transform.h"
#include "core/scene/loader/shape_factory.h"

namespace render::bench {

MeshData make_displaced_sphere(int rings, int segments) {
    MeshData mesh;
    mesh.positions.reserve(size_t(rings + 1) * size_t(segments));
    for (int i = 0; i <= rings; ++i) {
        const float theta = kPi * float(i) / float(rings);
        for (int j = 0; j < segments; ++j) {
            const float phi = 2.0f * kPi * float(j) / float(segments);
            const float r = 1.0f + 0.06f * std::sin(7.0f * theta) * std::sin(9.0f * phi) +
                            0.02f * std::sin(31.0f * theta + 3.0f * phi) +
                            0.008f * std::sin(97.0f * phi);
            mesh.positions.emplace_back(r * std::sin(theta) * std::cos(phi), r * std::cos(theta),
                                        r * std::sin(theta) * std::sin(phi));
        }
    }
    mesh.indices.reserve(size_t(rings) * size_t(segments) * 6);
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const uint32_t a = uint32_t(i * segments + j);
            const uint32_t b = uint32_t(i * segments + (j + 1) % segments);
            const uint32_t c = a + uint32_t(segments), d = b + uint32_t(segments);
            // Counter-clockwise seen from outside (normals point out).
            mesh.indices.insert(mesh.indices.end(), {a, b, c, b, d, c});
        }
    compute_vertex_normals(mesh, Transform());
    return mesh;
}

std::unique_ptr<Scene> make_procedural_scene() {
    auto scene = std::make_unique<Scene>();
    scene->source_file = "procedural-1M";
    const Bsdf* grey = scene->add_bsdf(std::make_shared<DiffuseBsdf>(Rgb(0.6f)));
    const Bsdf* ground = scene->add_bsdf(std::make_shared<DiffuseBsdf>(Rgb(0.4f)));
    scene->add_shape(std::make_unique<TriangleMesh>(make_displaced_sphere(512, 1024), Transform(),
                                                    false, false, "displaced-sphere"),
                     grey);
    // make_rectangle_mesh lies at z = 0 facing +z; turn it to face +y, below the sphere.
    const Transform floor = Transform::translate(Vec3(0.0f, -1.1f, 0.0f)) *
                            Transform::rotate(Vec3(1, 0, 0), -90.0f) *
                            Transform::scale(Vec3(6.0f, 6.0f, 1.0f));
    scene->add_shape(
        std::make_unique<TriangleMesh>(make_rectangle_mesh(), floor, false, false, "ground"),
        ground);
    scene->add_light(std::make_unique<PointLight>(Vec3(2.0f, 4.0f, 3.0f), Rgb(60.0f)));
    scene->set_camera(PerspectiveCamera(
        Transform::look_at(Vec3(0.0f, 0.8f, 3.6f), Vec3(0.0f, -0.1f, 0.0f), Vec3(0.0f, 1.0f, 0.0f)),
        45.0f, 'x', 512, 512));
    scene->commit();
    return scene;
}

}  // namespace render::bench
