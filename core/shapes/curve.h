#pragma once

// Curves (pbrt-v4's `curve`, Mitsuba 3's `bsplinecurve` and `linearcurve`) on Embree's curve
// geometry. Every input basis and degree is converted, exactly, to cubic Bezier segments in
// world space, one Embree primitive each; the segment knows the stretch [u0, u1] of its curve's
// u that it covers. Three kinds, as pbrt-v4 names them:
//   flat      a ribbon that always faces the ray (Embree's flat curves);
//   cylinder  a round tube (Embree's round curves: a swept sphere of the varying radius);
//   ribbon    a ribbon oriented by normals (Embree's normal-oriented curves).
// A hit reports the curve's u, v across the width (v = (1 + h) / 2, h in [-1, 1] the signed
// offset of the ray from the fibre axis that the hair BSDF reads, core/materials/hair.h), and a
// shading frame with s along the curve (dp/du), as the hair BSDF expects.
//
// Rays that leave a curve would hit the same tube or ribbon again (a flat curve turns to face
// every new ray); a filter drops hits on a segment whose tube contains the ray's origin, so light
// that the fibre model transmits passes through (pbrt-v4's ribbons let it through the same way).
// docs/reference/scene-format.md, "Curves", lists what differs from pbrt-v4 and Mitsuba.

#include <array>
#include <string>
#include <vector>

#include "core/base/shape.h"

namespace render {

enum class CurveType { Flat, Cylinder, Ribbon };

// One cubic Bezier segment in world space: control points, radii (Bezier-interpolated like the
// points), and for ribbons the normals at the control points.
struct CurveSegment {
    std::array<Vec3, 4> p;
    std::array<float, 4> radius;
    std::array<Vec3, 4> normal;  // ribbons only
    float u0 = 0, u1 = 1;        // the curve's u at the segment's ends
};

// Conversions of one curve's control points to cubic Bezier segments (positions only; `degree`
// 1, 2 or 3). Bezier input has degree * n + 1 points (segments share end points); B-spline
// input has at least degree + 1 (uniform knots, n = count - degree segments).
std::vector<std::array<Vec3, 4>> bezier_to_cubic(const std::vector<Vec3>& points, int degree);
std::vector<std::array<Vec3, 4>> bspline_to_cubic(const std::vector<Vec3>& points, int degree);
// The same for a quantity carried by the control points (Mitsuba's per-point radii).
std::vector<std::array<float, 4>> bspline_to_cubic(const std::vector<float>& values, int degree);

// Point and derivative of a cubic Bezier at t in [0, 1].
Vec3 bezier_point(const std::array<Vec3, 4>& p, float t);
Vec3 bezier_derivative(const std::array<Vec3, 4>& p, float t);
float bezier_value(const std::array<float, 4>& r, float t);

class Curves final : public Shape {
  public:
    // Throws SceneError (naming `name`) for no segments or a non-finite or negative radius.
    Curves(std::vector<CurveSegment> segments, CurveType type, std::string name);

    unsigned attach(RTCDevice device, RTCScene scene) const override;
    void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                          HitDetail detail, SurfaceInteraction& si) const override;
    Aabb bounds() const override;
    // Lateral area (flat curves and ribbons: both sides of width 2r; cylinders: 2 pi r), by
    // quadrature along each segment.
    float surface_area() const override;
    // Curves are not area lights (the loaders refuse one): a point on the first segment's axis,
    // with density zero so that nothing treats it as a sample.
    ShapeSample sample_area(Vec2 u) const override;
    std::string to_string() const override;

    CurveType type() const { return type_; }
    size_t segment_count() const { return segments_.size(); }
    const CurveSegment& segment(size_t i) const { return segments_[i]; }
    // Whether a ray starting at `origin` starts inside segment `prim`'s tube near parameter t
    // (the self-intersection filter).
    bool starts_inside(unsigned prim, float t, const Vec3& origin) const;

  private:
    std::vector<CurveSegment> segments_;
    CurveType type_;
    std::string name_;
};

}  // namespace render
