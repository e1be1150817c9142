#include "core/camera/perspective_camera.h"

#include <cmath>

#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

PerspectiveCamera::PerspectiveCamera(const Transform& to_world, float fov_degrees, char fov_axis,
                                     int width, int height)
    : to_world_(to_world),
      to_camera_(to_world.inverse()),
      fov_degrees_(fov_degrees),
      fov_axis_(fov_axis),
      width_(width),
      height_(height) {
    float tan_half = std::tan(0.5f * fov_degrees * kPi / 180.0f);
    float aspect = float(width) / float(height);
    if (fov_axis == 'y') {
        tan_half_y_ = tan_half;
        tan_half_x_ = tan_half * aspect;
    } else if (fov_axis == 'd') {
        // The diagonal: tan_half_x^2 + tan_half_y^2 = tan_half^2 with tan_half_y = x / aspect.
        tan_half_x_ = tan_half / std::sqrt(1.0f + 1.0f / (aspect * aspect));
        tan_half_y_ = tan_half_x_ / aspect;
    } else {
        tan_half_x_ = tan_half;
        tan_half_y_ = tan_half / aspect;
    }
    image_plane_area_ = 4.0f * tan_half_x_ * tan_half_y_;
    position_ = to_world.apply_point(Vec3(0, 0, 0));
    forward_ = normalize(to_world.apply_vector(Vec3(0, 0, 1)));
}

Ray PerspectiveCamera::generate_ray(Vec2 raster) const {
    // Raster x grows to the right, which is camera -x; raster y grows downward (camera -y).
    float cx = (1.0f - 2.0f * raster.x / float(width_)) * tan_half_x_;
    float cy = (1.0f - 2.0f * raster.y / float(height_)) * tan_half_y_;
    Vec3 dir = normalize(to_world_.apply_vector(Vec3(cx, cy, 1.0f)));
    return Ray(position_, dir);
}

std::optional<Vec2> PerspectiveCamera::raster_position(const Vec3& p) const {
    Vec3 local = to_camera_.apply_point(p);
    if (local.z <= 0) return std::nullopt;
    return raster_of(local.x / local.z, local.y / local.z);
}

float PerspectiveCamera::direction_pdf_w(const Vec3& dir) const {
    // Camera-space direction without the translation; to_camera may scale, so renormalise.
    Vec3 local = normalize(to_camera_.apply_vector(dir));
    if (local.z <= 0) return 0.0f;
    float cx = local.x / local.z, cy = local.y / local.z;
    if (std::abs(cx) > tan_half_x_ || std::abs(cy) > tan_half_y_) return 0.0f;
    float cos_theta = local.z;
    return 1.0f / (image_plane_area_ * cos_theta * cos_theta * cos_theta);
}

Vec3 PerspectiveCamera::local_lens_point(Vec2 u_lens) const {
    const Vec2 d = warp::square_to_uniform_disk_concentric(u_lens);
    return Vec3(lens_radius_ * d.x, lens_radius_ * d.y, 0.0f);
}

Ray PerspectiveCamera::generate_ray(Vec2 raster, Vec2 u_lens) const {
    if (!has_lens()) return generate_ray(raster);
    const float cx = (1.0f - 2.0f * raster.x / float(width_)) * tan_half_x_;
    const float cy = (1.0f - 2.0f * raster.y / float(height_)) * tan_half_y_;
    // Where the pinhole ray of this raster position meets the focus plane.
    const Vec3 focus(cx * focus_distance_, cy * focus_distance_, focus_distance_);
    const Vec3 lens = local_lens_point(u_lens);
    return Ray(to_world_.apply_point(lens), normalize(to_world_.apply_vector(focus - lens)));
}

std::optional<Vec2> PerspectiveCamera::raster_of(float cx, float cy) const {
    Vec2 raster((1.0f - cx / tan_half_x_) * 0.5f * float(width_),
                (1.0f - cy / tan_half_y_) * 0.5f * float(height_));
    if (!(raster.x >= 0 && raster.x < float(width_) && raster.y >= 0 && raster.y < float(height_)))
        return std::nullopt;
    return raster;
}

std::optional<PerspectiveCamera::LensConnection> PerspectiveCamera::connect(const Vec3& p,
                                                                            Vec2 u_lens) const {
    if (!has_lens()) {
        const std::optional<Vec2> raster = raster_position(p);
        if (!raster) return std::nullopt;
        return LensConnection{position_, *raster};
    }
    const Vec3 local = to_camera_.apply_point(p);
    if (!(local.z > 0)) return std::nullopt;
    const Vec3 lens = local_lens_point(u_lens);
    // The ray from the lens point through p meets the focus plane at `focus`; the pinhole ray
    // through that point gives the raster position.
    const Vec3 d = local - lens;
    const Vec3 focus = lens + d * (focus_distance_ / d.z);
    const std::optional<Vec2> raster =
        raster_of(focus.x / focus_distance_, focus.y / focus_distance_);
    if (!raster) return std::nullopt;
    return LensConnection{to_world_.apply_point(lens), *raster};
}

float PerspectiveCamera::direction_pdf_w(const Vec3& lens_point, const Vec3& dir) const {
    if (!has_lens()) return direction_pdf_w(dir);
    const Vec3 local = normalize(to_camera_.apply_vector(dir));
    if (local.z <= 0) return 0.0f;
    const Vec3 lens = to_camera_.apply_point(lens_point);
    const Vec3 focus = lens + local * ((focus_distance_ - lens.z) / local.z);
    const float cx = focus.x / focus_distance_, cy = focus.y / focus_distance_;
    if (std::abs(cx) > tan_half_x_ || std::abs(cy) > tan_half_y_) return 0.0f;
    const float cos_theta = local.z;
    return 1.0f / (image_plane_area_ * cos_theta * cos_theta * cos_theta);
}

}  // namespace render
