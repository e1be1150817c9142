#include "core/shapes/curve.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "core/base/error.h"
#include "core/math/constants.h"
#include "core/shapes/alpha_cutout.h"
#include "core/shapes/uv_wanted.h"

namespace render {
namespace {

template <class T>
std::array<T, 4> elevate_quadratic(const T& a, const T& b, const T& c) {
    // Degree elevation: the cubic with these points traces the quadratic exactly.
    return {a, a + (b - a) * (2.0f / 3.0f), c + (b - c) * (2.0f / 3.0f), c};
}

template <class T>
std::array<T, 4> elevate_linear(const T& a, const T& b) {
    return {a, a + (b - a) * (1.0f / 3.0f), a + (b - a) * (2.0f / 3.0f), b};
}

// Uniform B-spline segment (degree + 1 points from `p`) as a cubic Bezier.
template <class T>
std::array<T, 4> bspline_segment(const T* p, int degree) {
    if (degree == 1) return elevate_linear(p[0], p[1]);
    if (degree == 2) return elevate_quadratic((p[0] + p[1]) * 0.5f, p[1], (p[1] + p[2]) * 0.5f);
    return {(p[0] + p[1] * 4.0f + p[2]) * (1.0f / 6.0f), (p[1] * 2.0f + p[2]) * (1.0f / 3.0f),
            (p[1] + p[2] * 2.0f) * (1.0f / 3.0f), (p[1] + p[2] * 4.0f + p[3]) * (1.0f / 6.0f)};
}

template <class T>
std::vector<std::array<T, 4>> bspline_to_cubic_impl(const std::vector<T>& points, int degree) {
    std::vector<std::array<T, 4>> out;
    if (degree < 1 || degree > 3 || points.size() < size_t(degree) + 1) return out;
    for (size_t i = 0; i + size_t(degree) < points.size(); ++i)
        out.push_back(bspline_segment(&points[i], degree));
    return out;
}

// The hit's offset across the fibre, h in [-1, 1] (core/materials/hair.h). In the frame
// (s along the curve, n, t = n x s) and with wo = -ray direction: for a tube, the sine of the
// azimuthal angle between wo and the normal at the hit; for a ray-facing ribbon, the offset from
// the axis over the radius, with the same sign convention (the two agree where the ribbon is the
// tube's silhouette). Derivation: a ray from azimuth phi_o meeting the circle at azimuth phi_n
// reflects specularly to phi_o - 2 (phi_o - phi_n), the model's R lobe at gamma_o = phi_o - phi_n.
float offset_h(const Frame& frame, const Vec3& wo_world, const Vec3& from_axis, float radius) {
    const Vec3 wo = frame.to_local(wo_world), q = frame.to_local(from_axis);
    const float len = std::sqrt(wo.y * wo.y + wo.z * wo.z);
    if (!(len > 0) || !(radius > 0)) return 0;
    return std::clamp((wo.z * q.y - wo.y * q.z) / (len * radius), -1.0f, 1.0f);
}

// Embree's filter: drops hits on a segment whose tube holds the ray's origin (rays leaving the
// curve) and the hits a cut-out drops.
void curve_filter(const RTCFilterFunctionNArguments* args) {
    const auto* curves = static_cast<const Curves*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const float org[3] = {RTCRayN_org_x(args->ray, args->N, i),
                              RTCRayN_org_y(args->ray, args->N, i),
                              RTCRayN_org_z(args->ray, args->N, i)};
        const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
        const float u = RTCHitN_u(args->hit, args->N, i);
        if (curves->starts_inside(prim, u, Vec3(org[0], org[1], org[2]))) {
            args->valid[i] = 0;
            continue;
        }
        if (!curves->alpha) continue;
        const float dir[3] = {RTCRayN_dir_x(args->ray, args->N, i),
                              RTCRayN_dir_y(args->ray, args->N, i),
                              RTCRayN_dir_z(args->ray, args->N, i)};
        const CurveSegment& s = curves->segment(prim);
        const Vec2 uv(s.u0 + (s.u1 - s.u0) * u, RTCHitN_v(args->hit, args->N, i));
        if (!curves->alpha->keeps_hit(uv, org, dir, RTCRayN_tfar(args->ray, args->N, i)))
            args->valid[i] = 0;
    }
}

}  // namespace

std::vector<std::array<Vec3, 4>> bezier_to_cubic(const std::vector<Vec3>& p, int degree) {
    std::vector<std::array<Vec3, 4>> out;
    if (degree < 1 || degree > 3 || p.size() < size_t(degree) + 1 ||
        (p.size() - 1) % size_t(degree) != 0)
        return out;
    for (size_t i = 0; i + size_t(degree) < p.size(); i += size_t(degree)) {
        if (degree == 1) out.push_back(elevate_linear(p[i], p[i + 1]));
        if (degree == 2) out.push_back(elevate_quadratic(p[i], p[i + 1], p[i + 2]));
        if (degree == 3) out.push_back({p[i], p[i + 1], p[i + 2], p[i + 3]});
    }
    return out;
}

std::vector<std::array<Vec3, 4>> bspline_to_cubic(const std::vector<Vec3>& points, int degree) {
    return bspline_to_cubic_impl(points, degree);
}

std::vector<std::array<float, 4>> bspline_to_cubic(const std::vector<float>& values, int degree) {
    return bspline_to_cubic_impl(values, degree);
}

Vec3 bezier_point(const std::array<Vec3, 4>& p, float t) {
    const float s = 1 - t;
    return p[0] * (s * s * s) + p[1] * (3 * s * s * t) + p[2] * (3 * s * t * t) +
           p[3] * (t * t * t);
}

Vec3 bezier_derivative(const std::array<Vec3, 4>& p, float t) {
    const float s = 1 - t;
    return ((p[1] - p[0]) * (s * s) + (p[2] - p[1]) * (2 * s * t) + (p[3] - p[2]) * (t * t)) * 3.0f;
}

float bezier_value(const std::array<float, 4>& r, float t) {
    const float s = 1 - t;
    return r[0] * (s * s * s) + r[1] * (3 * s * s * t) + r[2] * (3 * s * t * t) +
           r[3] * (t * t * t);
}

Curves::Curves(std::vector<CurveSegment> segments, CurveType type, std::string name)
    : segments_(std::move(segments)), type_(type), name_(std::move(name)) {
    if (segments_.empty()) throw SceneError(name_ + ": the curve has no segments");
    for (const CurveSegment& s : segments_) {
        for (int k = 0; k < 4; ++k) {
            if (!(s.radius[size_t(k)] >= 0) || !std::isfinite(s.radius[size_t(k)]))
                throw SceneError(name_ + ": curve widths must be finite and non-negative");
            if (!is_finite(s.p[size_t(k)]))
                throw SceneError(name_ + ": curve control points must be finite");
        }
    }
}

unsigned Curves::attach(RTCDevice device, RTCScene scene) const {
    const RTCGeometryType kind = type_ == CurveType::Flat ? RTC_GEOMETRY_TYPE_FLAT_BEZIER_CURVE
                                 : type_ == CurveType::Cylinder
                                     ? RTC_GEOMETRY_TYPE_ROUND_BEZIER_CURVE
                                     : RTC_GEOMETRY_TYPE_NORMAL_ORIENTED_BEZIER_CURVE;
    RTCGeometry geometry = rtcNewGeometry(device, kind);
    const size_t n = segments_.size();
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 4 * n));
    auto* indices = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, sizeof(uint32_t), n));
    float* normals = nullptr;
    if (type_ == CurveType::Ribbon)
        normals = static_cast<float*>(rtcSetNewGeometryBuffer(
            geometry, RTC_BUFFER_TYPE_NORMAL, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 4 * n));
    for (size_t i = 0; i < n; ++i) {
        indices[i] = uint32_t(4 * i);
        for (size_t k = 0; k < 4; ++k) {
            float* v = vertices + 4 * (4 * i + k);
            const Vec3& p = segments_[i].p[k];
            v[0] = p.x, v[1] = p.y, v[2] = p.z, v[3] = segments_[i].radius[k];
            if (normals) {
                float* nn = normals + 3 * (4 * i + k);
                const Vec3& nk = segments_[i].normal[k];
                nn[0] = nk.x, nn[1] = nk.y, nn[2] = nk.z;
            }
        }
    }
    rtcSetGeometryUserData(geometry, const_cast<Curves*>(this));
    rtcSetGeometryIntersectFilterFunction(geometry, curve_filter);
    rtcSetGeometryOccludedFilterFunction(geometry, curve_filter);
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

bool Curves::starts_inside(unsigned prim, float t, const Vec3& origin) const {
    if (prim >= segments_.size()) return false;
    const CurveSegment& s = segments_[prim];
    const Vec3 c = bezier_point(s.p, t);
    const float r = bezier_value(s.radius, t);
    // 1.5 r: Embree's tube is a swept sphere, and a point leaving it may sit a little off the
    // cross-section at t; the absolute term covers the spawn offset of zero-width curves.
    const float scale = std::max({std::abs(c.x), std::abs(c.y), std::abs(c.z), 1.0f});
    const float reach = 1.5f * r + 1e-5f * scale;
    return length_squared(origin - c) <= reach * reach;
}

void Curves::fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                              HitDetail detail, SurfaceInteraction& si) const {
    const CurveSegment& s = segments_[std::min<size_t>(prim_id, segments_.size() - 1)];
    const Vec3 p = ray.origin + ray.direction * t;
    const Vec3 c = bezier_point(s.p, u);
    const float r = bezier_value(s.radius, u);
    Vec3 dpdu_segment = bezier_derivative(s.p, u);
    if (!(length_squared(dpdu_segment) > 0)) dpdu_segment = s.p[3] - s.p[0];
    const Vec3 tangent = length_squared(dpdu_segment) > 0 ? normalize(dpdu_segment) : Vec3(1, 0, 0);
    // The normal: perpendicular to the curve, toward the hit (tube), toward the ray (flat), or
    // the ribbon's interpolated normal.
    auto perpendicular = [&](const Vec3& w) { return w - tangent * dot(w, tangent); };
    Vec3 n;
    if (type_ == CurveType::Cylinder) {
        n = perpendicular(p - c);
    } else if (type_ == CurveType::Flat) {
        n = perpendicular(-ray.direction);
    } else {
        const float sv = 1 - u;
        n = perpendicular(s.normal[0] * (sv * sv * sv) + s.normal[1] * (3 * sv * sv * u) +
                          s.normal[2] * (3 * sv * u * u) + s.normal[3] * (u * u * u));
    }
    if (!(length_squared(n) > 0)) n = perpendicular(-ray.direction);
    if (!(length_squared(n) > 0)) n = Frame::from_normal(tangent).s;
    n = normalize(n);
    const Frame frame(tangent, cross(n, tangent), n);
    float h;
    if (type_ == CurveType::Ribbon)
        h = r > 0 ? std::clamp(dot(p - c, frame.t) / r, -1.0f, 1.0f) : 0.0f;
    else
        h = offset_h(frame, -ray.direction, p - c, r);
    // Embree's v is not the across-width offset for every curve type; h is
    si.p = p;
    si.t = t;
    si.geometric_normal = n;
    si.shading = frame;
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) {
        const float du = s.u1 - s.u0;
        si.uv = Vec2(s.u0 + du * u, 0.5f * (1 + h));
        si.dpdu = du > 0 ? dpdu_segment / du : dpdu_segment;
        si.dpdv = frame.t * (2 * r);
    }
    finish_interaction(prim_id, u, v, with_uv, si);
}

Aabb Curves::bounds() const {
    // A Bezier segment lies in its control points' hull; the tube within radius of it.
    Aabb b;
    for (const CurveSegment& s : segments_) {
        const float r = *std::max_element(s.radius.begin(), s.radius.end());
        for (const Vec3& p : s.p) {
            b.expand(p - Vec3(r));
            b.expand(p + Vec3(r));
        }
    }
    return b;
}

float Curves::surface_area() const {
    constexpr int kSteps = 16;  // midpoint rule per segment
    double area = 0;
    const double around = type_ == CurveType::Cylinder ? 2 * kPi : 4.0;  // 2 pi r or 2 x 2r
    for (const CurveSegment& s : segments_)
        for (int i = 0; i < kSteps; ++i) {
            const float t = (float(i) + 0.5f) / kSteps;
            area += double(length(bezier_derivative(s.p, t))) / kSteps * around *
                    double(bezier_value(s.radius, t));
        }
    return float(area);
}

ShapeSample Curves::sample_area(Vec2 u) const {
    ShapeSample s;
    s.p = bezier_point(segments_[0].p, u.x);
    s.n = Frame::from_normal(normalize(bezier_derivative(segments_[0].p, u.x) + Vec3(1e-20f))).s;
    s.pdf_area = 0;
    return s;
}

std::string Curves::to_string() const {
    std::ostringstream out;
    const char* kind = type_ == CurveType::Flat       ? "flat"
                       : type_ == CurveType::Cylinder ? "cylinder"
                                                      : "ribbon";
    out << "Curves[" << name_ << ", " << kind << ", " << segments_.size() << " segments]";
    return out.str();
}

}  // namespace render
