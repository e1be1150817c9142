#include "core/integrators/merge_radius.h"

#include <algorithm>
#include <cmath>

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

}  // namespace render
