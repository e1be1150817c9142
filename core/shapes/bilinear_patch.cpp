#include "core/shapes/bilinear_patch.h"

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

struct D3 {
    double x, y, z;
};
D3 d3(const Vec3& v) {
    return {v.x, v.y, v.z};
}
D3 operator-(const D3& a, const D3& b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
D3 operator+(const D3& a, const D3& b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
D3 operator*(const D3& a, double s) {
    return {a.x * s, a.y * s, a.z * s};
}
double dot(const D3& a, const D3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
D3 cross(const D3& a, const D3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
D3 lerp(double t, const D3& a, const D3& b) {
    return a * (1 - t) + b * t;
}
Vec3 to_vec3(const D3& a) {
    return Vec3(float(a.x), float(a.y), float(a.z));
}

// Real roots of a x^2 + b x + c = 0 (the linear case when a is negligible); returns how many.
int solve_quadratic(double a, double b, double c, double roots[2]) {
    const double scale = std::max({std::abs(a), std::abs(b), std::abs(c)});
    if (!(scale > 0)) return 0;
    if (std::abs(a) <= 1e-12 * scale) {
        if (b == 0) return 0;
        roots[0] = -c / b;
        return 1;
    }
    const double disc = b * b - 4 * a * c;
    if (disc < 0) return 0;
    // The form without cancellation (Numerical Recipes 5.6).
    const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
    roots[0] = q / a;
    roots[1] = q != 0 ? c / q : roots[0];
    return 2;
}

// x in [0, 1) with density 2 lerp(x, a, b) / (a + b), by inverting the CDF
// (a x + (b - a) x^2 / 2) 2 / (a + b); the form without cancellation when a ~ b.
float sample_linear(float u, float a, float b) {
    if (a == 0 && b == 0) return u;
    const float x = u * (a + b) / (a + std::sqrt(std::max(0.0f, (1 - u) * a * a + u * b * b)));
    return std::min(x, kOneMinusEpsilon);
}

// Gauss-Legendre nodes and weights on [0, 1] (8 points: exact for polynomials of degree 15;
// the area element is the square root of a polynomial, smooth on non-degenerate patches).
constexpr int kQuadraturePoints = 8;
constexpr double kNodes[kQuadraturePoints] = {
    0.019855071751231856, 0.10166676129318664, 0.2372337950418355, 0.4082826787521751,
    0.5917173212478249,   0.7627662049581645,  0.8983332387068134, 0.9801449282487681};
constexpr double kWeights[kQuadraturePoints] = {
    0.05061426814518813, 0.11119051722668724, 0.15685332293894363, 0.18134189168918100,
    0.18134189168918100, 0.15685332293894363, 0.11119051722668724, 0.05061426814518813};

}  // namespace

Vec2 sample_bilinear(Vec2 u, const std::array<float, 4>& w) {
    // The marginal in y is linear between the edge sums, then x given y is linear.
    const float y = sample_linear(u.y, w[0] + w[1], w[2] + w[3]);
    const float x = sample_linear(u.x, (1 - y) * w[0] + y * w[2], (1 - y) * w[1] + y * w[3]);
    return Vec2(x, y);
}

float bilinear_pdf(Vec2 p, const std::array<float, 4>& w) {
    if (!(p.x >= 0 && p.x <= 1 && p.y >= 0 && p.y <= 1)) return 0.0f;
    const float sum = w[0] + w[1] + w[2] + w[3];
    if (sum == 0) return 1.0f;
    return 4 *
           ((1 - p.x) * (1 - p.y) * w[0] + p.x * (1 - p.y) * w[1] + (1 - p.x) * p.y * w[2] +
            p.x * p.y * w[3]) /
           sum;
}

namespace {

void patch_bounds_callback(const RTCBoundsFunctionArguments* args) {
    const auto* shape = static_cast<const BilinearPatches*>(args->geometryUserPtr);
    Aabb b;
    for (int k = 0; k < 4; ++k) {
        // The patch lies in the convex hull of its corners.
        b.expand(shape->point(args->primID, k & 1, k >> 1));
    }
    *args->bounds_o = RTCBounds{b.lo.x, b.lo.y, b.lo.z, 0.0f, b.hi.x, b.hi.y, b.hi.z, 0.0f};
}

// Closest hits are single rays (rtcIntersect1), so N is always 1 here.
void patch_intersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* shape = static_cast<const BilinearPatches*>(args->geometryUserPtr);
    auto* rayhit = reinterpret_cast<RTCRayHit*>(args->rayhit);
    RTCRay& ray = rayhit->ray;
    const double org[3] = {ray.org_x, ray.org_y, ray.org_z};
    const double dir[3] = {ray.dir_x, ray.dir_y, ray.dir_z};
    const auto hit = shape->intersect_patch(args->primID, org, dir, ray.tnear, ray.tfar);
    if (!hit) return;
    ray.tfar = float(hit->t);
    RTCHit& h = rayhit->hit;
    h.Ng_x = h.Ng_y = h.Ng_z = 0;  // computed by fill_interaction()
    h.u = float(hit->u);
    h.v = float(hit->v);
    h.primID = args->primID;
    h.geomID = args->geomID;
    h.instID[0] = args->context->instID[0];
}

// Shadow rays come one at a time (rtcOccluded1, N = 1) or in packets of N from the stream
// query of Scene's batched occluded(): lane by lane.
void patch_occluded(const RTCOccludedFunctionNArguments* args) {
    const auto* shape = static_cast<const BilinearPatches*>(args->geometryUserPtr);
    RTCRayN* ray = args->ray;
    const unsigned n = args->N;
    for (unsigned i = 0; i < n; ++i) {
        if (!args->valid[i]) continue;
        const double org[3] = {RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                               RTCRayN_org_z(ray, n, i)};
        const double dir[3] = {RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                               RTCRayN_dir_z(ray, n, i)};
        if (shape->intersect_patch(args->primID, org, dir, RTCRayN_tnear(ray, n, i),
                                   RTCRayN_tfar(ray, n, i)))
            RTCRayN_tfar(ray, n, i) = -std::numeric_limits<float>::infinity();
    }
}

}  // namespace

BilinearPatches::BilinearPatches(std::vector<Vec3> positions, std::vector<uint32_t> indices,
                                 std::vector<Vec3> normals, std::vector<Vec2> uvs,
                                 bool flip_normals, std::string name)
    : positions_(std::move(positions)),
      indices_(std::move(indices)),
      normals_(std::move(normals)),
      uvs_(std::move(uvs)),
      flip_normals_(flip_normals),
      name_(std::move(name)) {
    if (indices_.empty() || indices_.size() % 4 != 0)
        throw SceneError(name_ + ": the patch index count, " + std::to_string(indices_.size()) +
                         ", is not a positive multiple of 4");
    for (uint32_t i : indices_)
        if (i >= positions_.size())
            throw SceneError(name_ + ": vertex index " + std::to_string(i) +
                             " out of range (the mesh has " + std::to_string(positions_.size()) +
                             " vertices)");
    for (const Vec3& p : positions_)
        if (!is_finite(p)) throw SceneError(name_ + ": non-finite vertex position");
    if (normals_.size() != positions_.size()) normals_.clear();
    if (uvs_.size() != positions_.size()) uvs_.clear();

    std::vector<float> areas(patch_count());
    patch_areas_.resize(patch_count());
    corner_weights_.resize(patch_count());
    double total = 0;
    for (size_t i = 0; i < patch_count(); ++i) {
        double a = 0;
        for (int x = 0; x < kQuadraturePoints; ++x)
            for (int y = 0; y < kQuadraturePoints; ++y)
                a += kWeights[x] * kWeights[y] * area_element(i, kNodes[x], kNodes[y]);
        if (!std::isfinite(a)) a = 0;
        patch_areas_[i] = a;
        areas[i] = float(a);
        total += a;
        for (int k = 0; k < 4; ++k) corner_weights_[i][k] = float(area_element(i, k & 1, k >> 1));
    }
    area_ = float(total);
    patch_distribution_ = Distribution1D(std::move(areas));
}

Vec3 BilinearPatches::point(size_t i, double u, double v) const {
    const D3 p = lerp(v, lerp(u, d3(corner(i, 0)), d3(corner(i, 1))),
                      lerp(u, d3(corner(i, 2)), d3(corner(i, 3))));
    return to_vec3(p);
}

double BilinearPatches::area_element(size_t i, double u, double v) const {
    const D3 p00 = d3(corner(i, 0)), p10 = d3(corner(i, 1)), p01 = d3(corner(i, 2)),
             p11 = d3(corner(i, 3));
    const D3 dpdu = lerp(v, p10 - p00, p11 - p01), dpdv = lerp(u, p01 - p00, p11 - p10);
    const D3 n = cross(dpdu, dpdv);
    return std::sqrt(dot(n, n));
}

Vec2 BilinearPatches::uv_of(size_t i, double u, double v) const {
    if (uvs_.empty()) return Vec2(float(u), float(1 - v));
    const uint32_t* k = &indices_[4 * i];
    const Vec2 a = uvs_[k[0]] * float(1 - u) + uvs_[k[1]] * float(u);
    const Vec2 b = uvs_[k[2]] * float(1 - u) + uvs_[k[3]] * float(u);
    return a * float(1 - v) + b * float(v);
}

std::optional<BilinearPatches::PatchHit> BilinearPatches::intersect_patch(
    size_t i, const double org[3], const double dir[3], double t_min, double t_max) const {
    const D3 o{org[0], org[1], org[2]}, d{dir[0], dir[1], dir[2]};
    const D3 p00 = d3(corner(i, 0)), p10 = d3(corner(i, 1)), p01 = d3(corner(i, 2)),
             p11 = d3(corner(i, 3));
    // The patch is swept by the segments A(u) -> A(u) + E(u), A(u) = lerp(u, p00, p10),
    // E(u) = lerp(u, p01 - p00, p11 - p10). The ray meets the line through a segment when
    // A(u) - o, E(u) and d are coplanar: f(u) = dot(cross(A(u) - o, d), E(u)) = 0, quadratic.
    const D3 q00 = p00 - o, q10 = p10 - o, e00 = p01 - p00, e11 = p11 - p10;
    const double c = dot(cross(q00, d), e00);   // f(0)
    const double f1 = dot(cross(q10, d), e11);  // f(1)
    const double a = dot(cross(p10 - p00, d), e11 - e00);
    const double b = f1 - a - c;
    double roots[2];
    const int n = solve_quadratic(a, b, c, roots);
    PatchHit found[2];
    int count = 0;
    for (int r = 0; r < n; ++r) {
        const double u = roots[r];
        if (!(u >= 0 && u <= 1)) continue;
        // o + t d = A(u) + v E(u): t d - v E = w with w = A(u) - o; crossing with E and with d
        // isolates t and v.
        const D3 w = lerp(u, q00, q10), e = lerp(u, e00, e11);
        const D3 m = cross(d, e);
        const double m2 = dot(m, m);
        if (!(m2 > 0)) continue;  // the ray runs along the segment's line
        const double t = dot(cross(w, e), m) / m2;
        const double v = dot(cross(w, d), m) / m2;
        if (!(v >= 0 && v <= 1 && t > t_min && t < t_max)) continue;
        found[count++] = {t, u, v};
    }
    if (count == 2 && found[1].t < found[0].t) std::swap(found[0], found[1]);
    for (int k = 0; k < count; ++k) {
        if (alpha) {
            const float fo[3] = {float(org[0]), float(org[1]), float(org[2])};
            const float fd[3] = {float(dir[0]), float(dir[1]), float(dir[2])};
            if (!alpha->keeps_hit(uv_of(i, found[k].u, found[k].v), fo, fd, float(found[k].t)))
                continue;
        }
        return found[k];
    }
    return std::nullopt;
}

unsigned BilinearPatches::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, unsigned(patch_count()));
    // Embree's API takes a non-const pointer; the callbacks only read the shape.
    rtcSetGeometryUserData(geometry, const_cast<BilinearPatches*>(this));
    rtcSetGeometryBoundsFunction(geometry, patch_bounds_callback, nullptr);
    rtcSetGeometryIntersectFunction(geometry, patch_intersect);
    rtcSetGeometryOccludedFunction(geometry, patch_occluded);
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

void BilinearPatches::fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                                       HitDetail detail, SurfaceInteraction& si) const {
    const size_t i = prim_id;
    const D3 p00 = d3(corner(i, 0)), p10 = d3(corner(i, 1)), p01 = d3(corner(i, 2)),
             p11 = d3(corner(i, 3));
    const D3 dpdu = lerp(v, p10 - p00, p11 - p01), dpdv = lerp(u, p01 - p00, p11 - p10);
    si.p = point(i, u, v);
    si.t = t;
    const D3 cn = cross(dpdu, dpdv);
    const double len = std::sqrt(dot(cn, cn));
    // A degenerate point (a collapsed corner): face the ray, as TriangleMesh does.
    Vec3 ng = len > 0 ? to_vec3(cn * (1 / len)) : -ray.direction;
    if (flip_normals_ && len > 0) ng = -ng;
    Vec3 ns = ng;
    if (!normals_.empty()) {
        const uint32_t* k = &indices_[4 * i];
        const Vec3 a = normals_[k[0]] * (1 - u) + normals_[k[1]] * u;
        const Vec3 b = normals_[k[2]] * (1 - u) + normals_[k[3]] * u;
        const Vec3 n = a * (1 - v) + b * v;
        const float nlen = length(n);
        if (nlen > 0 && std::isfinite(nlen)) {
            ns = n / nlen;
            // pbrt orients the surface by its vertex normals.
            if (dot(ng, ns) < 0) ng = -ng;
        }
    }
    si.geometric_normal = ng;
    si.shading = Frame::from_normal(ns);
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) {
        si.uv = uv_of(i, u, v);
        // dp/d(uv) = dp/d(u, v) J^-1 with J the Jacobian of the uv map.
        double j[2][2];  // j[r][c]: d uv_r / d (u, v)_c
        if (uvs_.empty()) {
            j[0][0] = 1, j[0][1] = 0, j[1][0] = 0, j[1][1] = -1;
        } else {
            const uint32_t* k = &indices_[4 * i];
            const Vec2 &t00 = uvs_[k[0]], &t10 = uvs_[k[1]], &t01 = uvs_[k[2]], &t11 = uvs_[k[3]];
            for (int r = 0; r < 2; ++r) {
                const double c00 = r ? t00.y : t00.x, c10 = r ? t10.y : t10.x,
                             c01 = r ? t01.y : t01.x, c11 = r ? t11.y : t11.x;
                j[r][0] = (1 - v) * (c10 - c00) + v * (c11 - c01);
                j[r][1] = (1 - u) * (c01 - c00) + u * (c11 - c10);
            }
        }
        const double det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        si.dpdu = si.dpdv = Vec3(0.0f);
        if (std::abs(det) > 0) {
            // Columns of J^-1 = [j11 -j01; -j10 j00] / det.
            const Vec3 a = to_vec3((dpdu * j[1][1] - dpdv * j[1][0]) * (1 / det));
            const Vec3 b = to_vec3((dpdv * j[0][0] - dpdu * j[0][1]) * (1 / det));
            if (is_finite(a)) si.dpdu = a;
            if (is_finite(b)) si.dpdv = b;
        }
    }
    finish_interaction(prim_id, u, v, with_uv, si);
}

Aabb BilinearPatches::patch_bounds(size_t i) const {
    Aabb b;
    for (int k = 0; k < 4; ++k) b.expand(corner(i, k));
    return b;
}

Aabb BilinearPatches::bounds() const {
    Aabb b;
    for (uint32_t i : indices_) b.expand(positions_[i]);
    return b;
}

ShapeSample BilinearPatches::sample_area(Vec2 u) const {
    ShapeSample s;
    if (!(area_ > 0)) return s;
    float probability, u_remapped;
    const size_t i = patch_distribution_.sample_discrete(u.x, &probability, &u_remapped);
    const Vec2 uv = sample_bilinear(Vec2(u_remapped, u.y), corner_weights_[i]);
    const double jacobian = area_element(i, uv.x, uv.y);
    if (!(jacobian > 0)) return s;  // a collapsed corner: no density
    SurfaceInteraction si;
    fill_interaction(Ray(), 0, unsigned(i), uv.x, uv.y, HitDetail::kWithUv, si);
    s.p = si.p;
    s.n = si.geometric_normal;
    s.uv = si.uv;
    s.pdf_area = float(probability * bilinear_pdf(uv, corner_weights_[i]) / jacobian);
    if (!std::isfinite(s.pdf_area)) s.pdf_area = 0;
    return s;
}

bool BilinearPatches::locate(const Vec3& p, unsigned& patch, Vec2& uv) const {
    const D3 target = d3(p);
    double best = kInfinity;
    for (size_t i = 0; i < patch_count(); ++i) {
        Aabb b = patch_bounds(i);
        const float size = std::max({b.hi.x - b.lo.x, b.hi.y - b.lo.y, b.hi.z - b.lo.z});
        const float margin = 1e-3f * size;
        if (p.x < b.lo.x - margin || p.y < b.lo.y - margin || p.z < b.lo.z - margin ||
            p.x > b.hi.x + margin || p.y > b.hi.y + margin || p.z > b.hi.z + margin)
            continue;
        const D3 p00 = d3(corner(i, 0)), p10 = d3(corner(i, 1)), p01 = d3(corner(i, 2)),
                 p11 = d3(corner(i, 3));
        // Gauss-Newton on |p(u, v) - target|^2 from the centre and, if that fails, the corners.
        const double starts[5][2] = {{0.5, 0.5}, {0.1, 0.1}, {0.9, 0.1}, {0.1, 0.9}, {0.9, 0.9}};
        for (const auto& start : starts) {
            double u = start[0], v = start[1], residual = kInfinity;
            for (int iteration = 0; iteration < 30; ++iteration) {
                const D3 r = lerp(v, lerp(u, p00, p10), lerp(u, p01, p11)) - target;
                residual = std::sqrt(dot(r, r));
                const D3 du = lerp(v, p10 - p00, p11 - p01), dv = lerp(u, p01 - p00, p11 - p10);
                const double a = dot(du, du), bb = dot(du, dv), c = dot(dv, dv);
                const double det = a * c - bb * bb;
                if (!(det > 0)) break;
                const double gu = dot(du, r), gv = dot(dv, r);
                const double step_u = (c * gu - bb * gv) / det, step_v = (a * gv - bb * gu) / det;
                u = std::clamp(u - step_u, -0.5, 1.5);
                v = std::clamp(v - step_v, -0.5, 1.5);
                if (std::abs(step_u) + std::abs(step_v) < 1e-12) break;
            }
            const double tolerance = 1e-4 * size + 1e-6 * std::max(1.0, double(length(p)));
            const double edge = 1e-5;
            if (residual < tolerance && u >= -edge && u <= 1 + edge && v >= -edge &&
                v <= 1 + edge) {
                if (residual < best) {
                    best = residual;
                    patch = unsigned(i);
                    uv = Vec2(float(std::clamp(u, 0.0, 1.0)), float(std::clamp(v, 0.0, 1.0)));
                }
                break;
            }
        }
    }
    return best < kInfinity;
}

float BilinearPatches::pdf_area(unsigned prim_id, Vec2 uv) const {
    const size_t i = prim_id;
    if (!(area_ > 0) || i >= patch_count()) return 0.0f;
    const double jacobian = area_element(i, uv.x, uv.y);
    if (!(jacobian > 0)) return 0.0f;
    const float pdf = float(patch_distribution_.discrete_probability(i) *
                            bilinear_pdf(uv, corner_weights_[i]) / jacobian);
    return std::isfinite(pdf) ? pdf : 0.0f;
}

Vec2 BilinearPatches::uv_at(const Vec3& p) const {
    unsigned i;
    Vec2 uv;
    if (!locate(p, i, uv)) return Vec2();
    return uv_of(i, uv.x, uv.y);
}

std::string BilinearPatches::to_string() const {
    std::ostringstream out;
    out << "BilinearPatches[" << name_ << ", " << patch_count() << " patches, area " << area_
        << "]";
    return out.str();
}

}  // namespace render
