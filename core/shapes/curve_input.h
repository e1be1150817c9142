#pragma once

// Curve segments from what scene files give: pbrt-v4's `curve` parameters (one curve: control
// points, basis, degree, widths at its ends, normals for ribbons) and Mitsuba 3's curve files
// (`bsplinecurve`, `linearcurve`: a text file of "x y z radius" lines, curves separated by
// empty lines). All geometry is in world space; core/shapes/curve.h converts nothing further.

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/shapes/curve.h"

namespace render {

enum class CurveBasis { Bezier, BSpline };

// pbrt-v4's curve: `points` (world space), `degree` 2 or 3, widths (full widths, world space)
// varying linearly in u from `width0` to `width1`, and for ribbons one normal per segment end
// (pbrt-v4's "N": segment count + 1 normals, slerped in between). Each segment covers an equal
// stretch of u. Throws SceneError (prefixed with `what`) for a control point count the basis
// and degree do not allow or a wrong normal count.
std::vector<CurveSegment> pbrt_curve_segments(const std::vector<Vec3>& points, CurveBasis basis,
                                              int degree, float width0, float width1,
                                              const std::vector<Vec3>& normals,
                                              const std::string& what);

// One curve of a Mitsuba curve file: control points and radii.
struct CurvePoints {
    std::vector<Vec3> points;
    std::vector<float> radii;
};

// Reads a Mitsuba 3 curve file. Throws SceneError naming the file and line for text that is not
// four finite numbers, a negative radius, or a file without control points.
std::vector<CurvePoints> read_curve_file(const std::filesystem::path& path);

// Mitsuba's `bsplinecurve` (cubic uniform B-splines, >= 4 points each) or `linearcurve`
// (polylines, >= 2 points each) as segments; u runs over [0, 1] along each curve. Throws
// SceneError (prefixed with `what`) for a curve with too few points.
std::vector<CurveSegment> mitsuba_curve_segments(const std::vector<CurvePoints>& curves,
                                                 bool bspline, const std::string& what);

}  // namespace render
