#include "core/shapes/curve_input.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/base/error.h"

namespace render {
namespace {

// Spherical interpolation of unit vectors (pbrt-v4 slerps its ribbon normals).
Vec3 slerp(const Vec3& a, const Vec3& b, float t) {
    const float c = std::clamp(dot(a, b), -1.0f, 1.0f);
    const float theta = std::acos(c);
    if (theta < 1e-4f) return normalize(a * (1 - t) + b * t);
    const float s = std::sin(theta);
    return a * (std::sin((1 - t) * theta) / s) + b * (std::sin(t * theta) / s);
}

std::array<float, 4> linear_radii(float r0, float r1) {
    // Bezier radii that interpolate linearly in the segment parameter.
    return {r0, r0 + (r1 - r0) / 3, r0 + 2 * (r1 - r0) / 3, r1};
}

}  // namespace

std::vector<CurveSegment> pbrt_curve_segments(const std::vector<Vec3>& points, CurveBasis basis,
                                              int degree, float width0, float width1,
                                              const std::vector<Vec3>& normals,
                                              const std::string& what) {
    if (degree != 2 && degree != 3)
        throw SceneError(what + ": \"degree\" must be 2 or 3 (got " + std::to_string(degree) + ")");
    std::vector<std::array<Vec3, 4>> cubic;
    if (basis == CurveBasis::Bezier) {
        if (points.size() < size_t(degree) + 1 || (points.size() - 1) % size_t(degree) != 0)
            throw SceneError(what + ": a degree " + std::to_string(degree) +
                             " Bezier curve needs " + std::to_string(degree) +
                             " n + 1 control points (got " + std::to_string(points.size()) + ")");
        cubic = bezier_to_cubic(points, degree);
    } else {
        if (points.size() < size_t(degree) + 1)
            throw SceneError(what + ": a degree " + std::to_string(degree) +
                             " B-spline needs at least " + std::to_string(degree + 1) +
                             " control points (got " + std::to_string(points.size()) + ")");
        cubic = bspline_to_cubic(points, degree);
    }
    const size_t n = cubic.size();
    if (!normals.empty() && normals.size() != n + 1)
        throw SceneError(what + ": a ribbon curve with " + std::to_string(n) + " segments needs " +
                         std::to_string(n + 1) + " normals \"N\" (got " +
                         std::to_string(normals.size()) + ")");
    std::vector<CurveSegment> out(n);
    for (size_t i = 0; i < n; ++i) {
        CurveSegment& s = out[i];
        s.p = cubic[i];
        s.u0 = float(i) / float(n);
        s.u1 = float(i + 1) / float(n);
        const float w0 = width0 + (width1 - width0) * s.u0, w1 = width0 + (width1 - width0) * s.u1;
        s.radius = linear_radii(0.5f * w0, 0.5f * w1);
        if (!normals.empty()) {
            const Vec3 a = normalize(normals[i]), b = normalize(normals[i + 1]);
            for (int k = 0; k < 4; ++k) s.normal[size_t(k)] = slerp(a, b, float(k) / 3);
        }
    }
    return out;
}

std::vector<CurvePoints> read_curve_file(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw SceneError(path.string() + ": cannot open the curve file");
    std::vector<CurvePoints> curves;
    bool new_curve = true;
    std::string line;
    int line_number = 0;
    while (std::getline(in, line)) {
        ++line_number;
        const size_t first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos) {  // an empty line ends the curve
            new_curve = true;
            continue;
        }
        if (line[first] == '#') continue;
        std::istringstream fields(line);
        double x, y, z, r;
        std::string rest;
        if (!(fields >> x >> y >> z >> r) || (fields >> rest) || !std::isfinite(x) ||
            !std::isfinite(y) || !std::isfinite(z) || !std::isfinite(r) || r < 0)
            throw SceneError(path.string() + ":" + std::to_string(line_number) +
                             ": expected \"x y z radius\" (four finite numbers, radius >= 0)");
        if (new_curve) curves.emplace_back();
        new_curve = false;
        curves.back().points.emplace_back(float(x), float(y), float(z));
        curves.back().radii.push_back(float(r));
    }
    if (curves.empty()) throw SceneError(path.string() + ": no control points");
    return curves;
}

std::vector<CurveSegment> mitsuba_curve_segments(const std::vector<CurvePoints>& curves,
                                                 bool bspline, const std::string& what) {
    std::vector<CurveSegment> out;
    for (size_t c = 0; c < curves.size(); ++c) {
        const CurvePoints& curve = curves[c];
        const size_t minimum = bspline ? 4 : 2;
        if (curve.points.size() < minimum)
            throw SceneError(what + ": curve " + std::to_string(c) + " has " +
                             std::to_string(curve.points.size()) + " control points (" +
                             (bspline ? "a B-spline needs 4" : "a polyline needs 2") + ")");
        const int degree = bspline ? 3 : 1;
        const auto p = bspline_to_cubic(curve.points, degree);
        const auto r = bspline_to_cubic(curve.radii, degree);
        const size_t n = p.size();
        for (size_t i = 0; i < n; ++i) {
            CurveSegment s;
            s.p = p[i];
            s.radius = r[i];
            s.u0 = float(i) / float(n);
            s.u1 = float(i + 1) / float(n);
            out.push_back(s);
        }
    }
    return out;
}

}  // namespace render
