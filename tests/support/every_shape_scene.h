#pragma once

// A scene with every kind of shape (rectangle, sphere, cube, disk, serialized mesh, an instance
// of a group) under one area light, all with the same material, for the tests of BSDFs that
// tilt the shading frame (normal_map_test, bump_map_test): each shape's tangents and uv must
// drive the tilt the same way. Header-only, so that RENDER_SOURCE_DIR is the test's.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <set>
#include <string>

#include "core/base/error.h"
#include "core/camera/perspective_camera.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/scene.h"

namespace render::testing {

// The scene's first 4 lines (camera, light); a body added after it starts on line 5.
inline const std::string kEveryShapeHead =
    "<scene version=\"3.0.0\">\n"
    "<sensor type=\"perspective\"><float name=\"fov\" value=\"50\"/>"
    "<transform name=\"to_world\"><lookat origin=\"0, 3, 6\" target=\"0, 0.3, 0\" "
    "up=\"0, 1, 0\"/></transform>"
    "<film type=\"hdrfilm\"><integer name=\"width\" value=\"48\"/>"
    "<integer name=\"height\" value=\"32\"/></film></sensor>\n"
    "<shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"0.5\"/>"
    "<rotate x=\"1\" angle=\"90\"/><translate y=\"4\"/></transform>"
    "<emitter type=\"area\"><rgb name=\"radiance\" value=\"10\"/></emitter></shape>\n"
    "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"0.2\"/></emitter>\n";

// The folder the scenes' files (meshes/pyramid.serialized, textures) are resolved in.
inline const std::string kEveryShapeDir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests";

// Every shape kind with material `bsdf` (a <bsdf> element or a <ref>).
inline std::string every_shape(const std::string& bsdf) {
    return "<shape type=\"rectangle\">" + bsdf +
           "<transform name=\"to_world\"><scale x=\"3\" y=\"2\"/><rotate x=\"1\" angle=\"-90\"/>"
           "<rotate y=\"1\" angle=\"20\"/></transform></shape>\n"
           "<shape type=\"sphere\">" +
           bsdf +
           "<point name=\"center\" x=\"-1.2\" y=\"0.6\" z=\"0\"/><float name=\"radius\" "
           "value=\"0.6\"/>"
           "<transform name=\"to_world\"><rotate x=\"1\" angle=\"-70\"/></transform></shape>\n"
           "<shape type=\"cube\">" +
           bsdf +
           "<transform name=\"to_world\"><scale value=\"0.4\"/><rotate y=\"1\" angle=\"30\"/>"
           "<translate x=\"1.2\" y=\"0.4\"/></transform></shape>\n"
           "<shape type=\"disk\">" +
           bsdf +
           "<transform name=\"to_world\"><scale value=\"0.5\"/><rotate x=\"1\" angle=\"-60\"/>"
           "<translate z=\"1.2\" y=\"0.5\"/></transform></shape>\n"
           "<shape type=\"serialized\">" +
           bsdf +
           "<string name=\"filename\" value=\"meshes/pyramid.serialized\"/>"
           "<transform name=\"to_world\"><scale value=\"0.5\"/><translate x=\"0.2\" z=\"-1\"/>"
           "</transform></shape>\n"
           "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\">" +
           bsdf +
           "<float name=\"radius\" value=\"0.3\"/></shape></shape>\n"
           "<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\">"
           "<scale x=\"1.5\" y=\"0.8\" z=\"1\"/><translate x=\"1.4\" y=\"0.3\" z=\"1.2\"/>"
           "</transform></shape>\n";
}

// kEveryShapeHead, then `bsdf_definition`, then every shape with material `bsdf`.
inline std::unique_ptr<Scene> load_every_shape_scene(const std::string& bsdf_definition,
                                                     const std::string& bsdf) {
    return load_scene_from_string(
        kEveryShapeHead + bsdf_definition + every_shape(bsdf) + "</scene>\n", kEveryShapeDir);
}

// The error of loading kEveryShapeHead + `body` (no shapes), or "loaded".
inline std::string every_shape_load_error(const std::string& body) {
    try {
        load_scene_from_string(kEveryShapeHead + body + "</scene>\n", kEveryShapeDir);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "loaded";
}

// Checks on every camera hit of the every-shape scene that the tangent dp/du (axis 0) or dp/dv
// (axis 1) points where uv moves along that axis alone, at unit rate: a step of 1e-3 along it,
// projected back onto the surface, changes uv by (1, 0) or (0, 1) times the step (within 0.02).
// Hits whose step crosses a seam or an edge are skipped; at least 400 hits on all 6 shapes.
inline void expect_tangent_follows_uv(const Scene& scene, int axis) {
    const PerspectiveCamera camera = scene.camera();
    int checked = 0;
    std::set<const Shape*> shapes_checked;
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 48; ++x) {
            SurfaceInteraction si;
            if (!scene.intersect(camera.generate_ray(Vec2(x + 0.5f, y + 0.5f)), si,
                                 HitDetail::kWithUv))
                continue;
            const Vec3 tangent = axis == 0 ? si.dpdu : si.dpdv;
            const float len = length(tangent);
            if (!(len > 0)) continue;  // poles, the disk's centre
            const float step = 1e-3f / len;
            const Vec3 n = si.geometric_normal;
            const Vec3 q = si.p + tangent * step;
            SurfaceInteraction sq;
            if (!scene.intersect(Ray(q + n * 0.01f, -n), sq, HitDetail::kWithUv) ||
                sq.shape != si.shape)
                continue;
            const Vec2 d = (sq.uv - si.uv) * (1.0f / step);
            const float along = axis == 0 ? d.x : d.y, across = axis == 0 ? d.y : d.x;
            if (std::abs(along) > 10) continue;  // across a seam (u or v wraps) or an edge
            EXPECT_NEAR(along, 1.0f, 0.02f) << si.shape->to_string() << " at " << x << ", " << y;
            EXPECT_NEAR(across, 0.0f, 0.02f) << si.shape->to_string() << " at " << x << ", " << y;
            ++checked;
            shapes_checked.insert(si.shape);
        }
    EXPECT_GT(checked, 400);
    // The floor, the sphere, the cube, the disk, the serialized pyramid, the instance.
    EXPECT_EQ(shapes_checked.size(), 6u);
}

}  // namespace render::testing
