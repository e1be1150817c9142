#pragma once

// An environment map: an infinite background whose radiance comes from a latitude-longitude
// image (Mitsuba's `envmap` emitter: `filename`, `scale`, `to_world`).
//
// Mapping (Mitsuba 3's, in the light's local frame, +y up): a local unit direction d has
//     u = atan2(d.x, -d.z) / (2 pi)  wrapped to [0, 1),   v = acos(d.y) / pi,
// and, inversely, with theta = pi v and phi = 2 pi u,
//     d = (sin phi sin theta, cos theta, -cos phi sin theta).
// So the top image row is +y (up), the image centre column (u = 1/2) looks along +z, and
// u = 0 (the left edge) along -z. Texel (col, row) of a W x H image covers
// u in [col / W, (col + 1) / W) and v in [row / H, (row + 1) / H); its centre is
// ((col + 1/2) / W, (row + 1/2) / H), which is where Mitsuba 3 puts pixel centres in u.
// World directions are d_world = to_world(d_local); to_world must be a rotation (possibly
// mirrored, possibly uniformly scaled: the scale is ignored).
//
// Lookup is nearest-texel (piecewise constant), so the radiance and the sampling density are
// constant over the same cells: illuminate() samples (u, v) from a piecewise-constant
// Distribution2D proportional to luminance(texel) * sin(theta at the row centre), and the
// solid-angle density of a direction is pdf_uv(u, v) / (2 pi^2 sin theta).
//
// Conventions otherwise as ConstantLight (SmallVCM's background light), with the uniform
// 1 / (4 pi) replaced by that density p(wi):
//   illuminate(): pdf_direct_w = p(wi), pdf_emission_w = p(wi) / (pi R^2).
//   emit():       wi ~ p, the ray travels along -wi from the scene disk; energy = Le(wi),
//                 pdf_emission_w = p(wi) / (pi R^2), pdf_direct_a = p(wi).
//   radiance():   for a ray escaping along `ray_direction` = wi: Le(wi), pdf_direct_a = p(wi),
//                 pdf_emission_w = p(wi) / (pi R^2).
//   power():      pi R^2 * integral of Le over the sphere (summed exactly over texels).
// Directions exactly at a pole have p = 0 (measure zero). Non-finite or negative texel values
// are read as 0, and the sampling weights are normalised to their maximum, so a single very
// bright texel cannot overflow the distribution.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/lights/light.h"
#include "core/math/frame.h"
#include "core/math/transform.h"
#include "core/sampling/distribution.h"

namespace render {

class EnvmapLight final : public Light {
  public:
    // `texels`: width * height linear RGB values, row-major, top row first, already scaled.
    // `to_world`: orthonormal images of the local x, y, z axes.
    EnvmapLight(std::vector<Rgb> texels, int width, int height, const Frame& to_world,
                std::string name = "");

    // Reads a lat-long image (read_image_file: EXR through OpenEXR; HDR, PNG, ... through
    // OpenImageIO in the image plugin, loaded then; 8/16-bit sRGB files are linearised) and
    // multiplies it by `scale`. Throws SceneError naming the path when the file is missing or
    // unreadable (with the reader's message, or the plugin's when it cannot be loaded).
    static std::unique_ptr<EnvmapLight> load(const std::filesystem::path& filename, float scale,
                                             const Frame& to_world);

    // The rotation part of a transform, or nothing if it is not a (uniformly scaled,
    // possibly mirrored) rotation.
    static std::optional<Frame> rotation_frame(const Transform& to_world);

    // The lat-long mapping in local space (see above).
    static Vec2 direction_to_uv(const Vec3& local_direction);
    static Vec3 uv_to_direction(Vec2 uv);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return false; }
    bool is_finite() const override { return false; }
    bool is_infinite_background() const override { return true; }
    std::string to_string() const override;

    // Solid-angle density of illuminate() choosing the world direction wi.
    float pdf_direction(const Vec3& wi) const;
    int width() const { return width_; }
    int height() const { return height_; }

  private:
    struct Lookup {
        Rgb radiance;
        float pdf_w = 0;
    };
    // Radiance arriving from world direction wi, and the density of sampling it.
    Lookup lookup(const Vec3& wi) const;
    // Samples a world direction toward the map; false if it carries no energy.
    bool sample_direction(Vec2 u, Vec3& wi, Lookup& value) const;

    std::vector<Rgb> texels_;
    int width_ = 0, height_ = 0;
    Frame to_world_;
    Distribution2D distribution_;
    Rgb radiance_integral_;  // integral of Le over the sphere
    std::string name_;
};

}  // namespace render
