#include "core/integrators/merge_radius.h"

#include <algorithm>
#include <cmath>

#include "core/camera/perspective_camera.h"
#include "core/lights/light.h"

namespace render {

double min_merge_radius() {
    return 1e-18;
}

double merge_radius(double r1, double alpha, uint64_t iteration) {
    return merge_radius_in(r1, alpha, iteration, 2);
}

double merge_radius_in(double r1, double alpha, uint64_t iteration, int dimension) {
    double i = double(std::max<uint64_t>(iteration, 1));
    return std::max(r1 * std::pow(i, (alpha - 1.0) / double(dimension)), min_merge_radius());
}

double pixel_footprint(const PerspectiveCamera& camera, const SceneSphere& sphere) {
    const double pixels = double(camera.width()) * double(camera.height());
    const double side_at_unit_distance = std::sqrt(double(camera.image_plane_area()) / pixels);
    const Vec3 to_centre = sphere.center - camera.position();
    const double distance = std::max(double(length(to_centre)), double(sphere.radius));
    return side_at_unit_distance * distance;
}

double initial_merge_radius(double radius_factor, double radius_pixels,
                            const PerspectiveCamera& camera, const SceneSphere& sphere) {
    if (radius_factor > 0) return radius_factor * double(sphere.radius);
    return radius_pixels * pixel_footprint(camera, sphere);
}

}  // namespace render
