#include "core/base/ray_transform_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/base/scene_limits.h"
#include "core/math/transform.h"

namespace render {
namespace {

std::string number(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", x);
    return std::string(buf);
}

}  // namespace

std::string ray_transform_problem(const Transform& t) {
    for (const auto& row : t.matrix())
        for (double x : row)
            if (!std::isfinite(x)) return "the transform is not finite";
    const double det = t.determinant3x3();
    if (t.is_singular() || det == 0 || !std::isfinite(det))
        return "the transform is singular (determinant " + number(det) + ")";
    const Transform::Matrix& m = t.matrix();
    const Transform inverse = t.inverse();
    const Transform::Matrix& inv = inverse.matrix();
    // Where a point within the limits can land in the shape's space, per axis: through the
    // linear part alone (`stretch`) and with the translation (`reach`).
    double norm2 = 0, inv_norm2 = 0, stretch = 0, reach = 0;
    for (int i = 0; i < 3; ++i) {
        double row = 0;
        for (int j = 0; j < 3; ++j) {
            norm2 += m[i][j] * m[i][j];
            inv_norm2 += inv[i][j] * inv[i][j];
            row += std::abs(inv[i][j]) * double(kMaxSceneCoordinate);
        }
        stretch = std::max(stretch, row);
        reach = std::max(reach, row + std::abs(inv[i][3]));
    }
    const double condition = std::sqrt(norm2) * std::sqrt(inv_norm2);
    if (!(condition <= kMaxTransformCondition))
        return "the transform is near-singular (determinant " + number(det) +
               ", condition number " + number(condition) + ", at most " +
               number(kMaxTransformCondition) + " is accepted)";
    if (!(reach <= kMaxObjectSpaceCoordinate))
        return std::string(stretch <= kMaxObjectSpaceCoordinate
                               ? "the transform moves too far"
                               : "the transform shrinks too much") +
               ": a point within the scene limits (" + number(kMaxSceneCoordinate) +
               " from the origin) would be " + number(reach) +
               " from the shape's origin in its own space, beyond what the ray tracer accepts (" +
               number(kMaxObjectSpaceCoordinate) + ")";
    return {};
}

}  // namespace render
