#pragma once

// Pinhole perspective camera with Mitsuba's conventions: camera space looks down +z with +y up
// and +x to the *left* of the image; `fov` is measured along `fov_axis`.
//
// For light tracing it also provides the importance We and the raster position of a world
// point. With the image plane at distance 1 and area A (in camera units), a pinhole's
// importance is We = 1 / (A cos^4 theta), and the solid-angle density of a camera ray direction
// is We cos theta = 1 / (A cos^3 theta) (direction_pdf_w).
//
// A thin lens (pbrt's `lensradius`/`focaldistance`, Mitsuba's `thinlens`) replaces the pinhole
// by a disk of radius r in the camera's z = 0 plane: a camera ray starts at a uniform lens
// point and passes through the point of the focus plane z = focus_distance that the pinhole ray
// of its raster position reaches. Seen from one lens point the focus plane's image window is a
// pinhole's image plane at distance focus_distance, so the direction density per lens point is
// again 1 / (A cos^3 theta) inside that window. The lens point's area density 1 / (pi r^2)
// cancels between a camera ray and a light path's connection to a sampled lens point: light
// tracing weighs a connection with the direction density at its lens point exactly as a
// pinhole's.

#include <optional>

#include "core/math/ray.h"
#include "core/math/transform.h"
#include "core/sampling/rng.h"

namespace render {

class PerspectiveCamera {
  public:
    PerspectiveCamera() = default;
    // fov in degrees along fov_axis ('x', 'y' or 'd', the diagonal); width, height in pixels.
    PerspectiveCamera(const Transform& to_world, float fov_degrees, char fov_axis, int width,
                      int height);

    // The same camera with another resolution; the field of view along fov_axis is kept.
    PerspectiveCamera with_resolution(int width, int height) const {
        PerspectiveCamera c(to_world_, fov_degrees_, fov_axis_, width, height);
        c.set_thin_lens(lens_radius_, focus_distance_);
        return c;
    }

    // A thin lens of radius lens_radius (camera units; 0: the pinhole) focused at
    // focus_distance (> 0) along the view axis.
    void set_thin_lens(float lens_radius, float focus_distance) {
        lens_radius_ = lens_radius;
        focus_distance_ = focus_distance;
    }
    bool has_lens() const { return lens_radius_ > 0; }
    float lens_radius() const { return lens_radius_; }
    float focus_distance() const { return focus_distance_; }

    int width() const { return width_; }
    int height() const { return height_; }
    Vec3 position() const { return position_; }
    Vec3 forward() const { return forward_; }

    // Primary ray through raster position (x, y) in [0, width) x [0, height), from the pinhole
    // (or the lens centre).
    Ray generate_ray(Vec2 raster) const;
    // The same from the lens point of u_lens (uniform on the lens disk); the pinhole ray without
    // a lens. Callers draw u_lens only when has_lens(), so that pinhole images stay as they were.
    Ray generate_ray(Vec2 raster, Vec2 u_lens) const;

    // A uniform lens point for u_lens (the camera position without a lens) and the raster
    // position at which the ray from it toward world point p lands; empty when p is behind the
    // lens or off the image.
    struct LensConnection {
        Vec3 lens_point;
        Vec2 raster;
    };
    std::optional<LensConnection> connect(const Vec3& p, Vec2 u_lens) const;

    // The integrators' entry points: they draw the lens sample from rng only with a lens.
    Ray sample_ray(Vec2 raster, Rng& rng) const {
        return has_lens() ? generate_ray(raster, rng.next_2d()) : generate_ray(raster);
    }
    std::optional<LensConnection> sample_connection(const Vec3& p, Rng& rng) const {
        return connect(p, has_lens() ? rng.next_2d() : Vec2());
    }

    // Raster position of the camera ray toward world point p; empty if p is behind the camera
    // or outside the image.
    std::optional<Vec2> raster_position(const Vec3& p) const;

    // Solid-angle density 1 / (A cos^3) of generate_ray producing world direction `dir` for a
    // uniformly chosen raster position; zero outside the image. We = direction_pdf_w / cos.
    float direction_pdf_w(const Vec3& dir) const;
    // The same for a ray from lens point `lens_point` (world space); direction_pdf_w(dir) without
    // a lens.
    float direction_pdf_w(const Vec3& lens_point, const Vec3& dir) const;

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
    float lens_radius_ = 0;
    float focus_distance_ = 1;

    // Raster position of camera-space focus-plane coordinates (x/f, y/f); empty off the image.
    std::optional<Vec2> raster_of(float cx, float cy) const;
    Vec3 local_lens_point(Vec2 u_lens) const;
};

}  // namespace render
