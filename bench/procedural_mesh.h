#pragma once

// A procedural test scene for the ray-query benchmarks: a displaced, finely tessellated sphere of
// at least one million triangles on a ground quad, lit by a point light, built in memory
// (nothing is read from disk).

#include <cstdint>
#include <memory>

#include "core/scene/scene.h"
#include "core/shapes/triangle_mesh.h"

namespace render::bench {

// A UV sphere of radius about 1 with `rings` x `segments` quads of 2 triangles each (the
// zero-area triangles at the poles are kept) whose radius is displaced by a sum of sines, so that
// the BVH sees a bumpy surface rather than a perfect sphere. Smooth vertex normals included.
MeshData make_displaced_sphere(int rings, int segments);

// The committed scene "procedural-1M": make_displaced_sphere(512, 1024) (1,048,576 triangles),
// a ground plane, a point light and a 512 x 512 camera.
std::unique_ptr<Scene> make_procedural_scene();

}  // namespace render::bench
