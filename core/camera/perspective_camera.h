#pragma once

// Pinhole perspective camera with Mitsuba's conventions: camera space looks down +z with +y up
// and +x to the *left* of the image; `fov` is measured along `fov_axis`.
//
// For light tracing it also provides the importance We and the raster position of a world
// point. With the image plane at distance 1 and area A (in camera units), a pinhole's
// importance is We = 1 / (A cos^4 theta), and the solid-angle density of a camera ray direction
// is We cos theta = 1 / (A cos^3 theta) (direction_pdf_w).

#include <optional>

#include "core/math/ray.h"
#include "core/math/transform.h"

namespace render {

class PerspectiveCamera {
  public:
    PerspectiveCamera() = default;
    // fov in degrees along fov_axis ('x', 'y' or 'd', the diagonal); width, height in pixels.
    PerspectiveCamera(const Transform& to_world, float fov_degrees, char fov_axis, int width,
                      int height);

    // The same camera with another resolution; the field of view along fov_axis is kept.
    PerspectiveCamera with_resolution(int width, int height) const {
        return PerspectiveCamera(to_world_, fov_degrees_, fov_axis_, width, height);
    }

    int width() const { return width_; }
    int height() const { return height_; }
    Vec3 position() const { return position_; }
    Vec3 forward() const { return forward_; }

    // Primary ray through raster position (x, y) in [0, width) x [0, height).
    Ray generate_ray(Vec2 raster) const;

    // Raster position of the camera ray toward world point p; empty if p is behind the camera
    // or outside the image.
    std::optional<Vec2> raster_position(const Vec3& p) const;

    // Solid-angle density 1 / (A cos^3) of generate_ray producing world direction `dir` for a
    // uniformly chosen raster position; zero outside the image. We = direction_pdf_w / cos.
    float direction_pdf_w(const Vec3& dir) const;

    // Area of the image plane at distance 1 from the pinhole.
    float image_plane_area() const { return image_plane_area_; }

  private:
    Transform to_world_;
    Transform to_camera_;
    float fov_degrees_ = 90;
    char fov_axis_ = 'x';
    Vec3 position_;
    Vec3 forward_;
    int width_ = 1, height_ = 1;
    float tan_half_x_ = 1, tan_half_y_ = 1;
    float image_plane_area_ = 4;
};

}  // namespace render
