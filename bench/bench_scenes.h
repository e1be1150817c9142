#pragma once

// Scenes and precomputed inputs shared by the benchmarks: shipped scenes by file stem, the
// procedural 1 M triangle scene, fixed-seed ray sets and light-subpath vertex positions. Every
// input is built once per process (on first use) and never timed.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/math/ray.h"
#include "core/math/vec.h"
#include "core/scene/scene.h"

namespace render::bench {

// Scenes of the ray-query group: the shipped scenes plus "procedural-1M".
const std::vector<std::string>& ray_scene_names();
// The four reference Cornell boxes of SmallVCM (scenes/smallvcm/*.xml), by stem.
const std::vector<std::string>& reference_scene_names();
// The shipped scenes with participating media (docs/design/media.md).
const std::vector<std::string>& media_scene_names();

// The scene file of a shipped scene's stem (e.g. "veach-mis", "1-glm_c").
std::filesystem::path scene_path(const std::string& name);

// The committed scene `name` at its file's own resolution (or the procedural one), loaded once.
const Scene& scene(const std::string& name);

// Rays over the scene, generated with a fixed seed:
//  closest: one camera ray per pixel of a 256 x 256 grid over the image, then for every first
//           hit one cosine-distributed ray about the geometric normal (facing the camera side);
//  shadow:  for every first hit one ray toward a point sampled on a light (power-proportional
//           light choice, Light::illuminate), offset at both ends as the integrators do.
struct RaySet {
    std::vector<Ray> closest;
    std::vector<Ray> shadow;
};
const RaySet& rays(const std::string& name);

// Positions of the light-subpath vertices of one VCM iteration: `path_count` light paths
// (sample_light -> emit -> intersect, then BSDF sampling in importance mode, continuing with
// probability min(sampled weight, 0.95), at most `max_vertices` hits), a vertex at every hit
// whose BSDF has a non-delta lobe (the vertices VCM stores and merges with). Fixed seed.
std::vector<Vec3> light_vertex_positions(const Scene& scene, uint64_t path_count,
                                         int max_vertices = 16);

// Positions of the eye-subpath vertices of one iteration: one jittered camera ray per pixel at
// the scene's resolution, continued like the light paths above in radiance mode. VCM queries the
// grid at each of them (every non-delta eye vertex).
std::vector<Vec3> eye_vertex_positions(const Scene& scene, int max_vertices = 16);

}  // namespace render::bench
