#pragma once

// The acceptance probabilities of the importance-driven VPL distribution (Georgiev and
// Slusallek 2010): candidate k with estimated image contribution phi[k] is kept with
//     P_k = max(min(M phi_k / phi, 1), min_probability),   phi = sum of phi_k, M candidates,
// and every P_k = 1 when phi is 0 (nothing seen: no basis for preferring any VPL). Any P_k in
// (0, 1] keeps the estimator unbiased once the kept VPLs' power is divided by P_k; the formula
// only decides the variance. Non-finite or negative estimates count as 0.

#include <algorithm>
#include <cmath>
#include <vector>

namespace render {

inline std::vector<double> vpl_keep_probabilities(const std::vector<double>& phi,
                                                  double min_probability) {
    auto usable = [](double x) { return std::isfinite(x) && x > 0 ? x : 0.0; };
    double total = 0;
    for (double x : phi) total += usable(x);
    std::vector<double> p(phi.size(), 1.0);
    if (!(total > 0) || !std::isfinite(total)) return p;
    const double m = double(phi.size());
    for (size_t k = 0; k < phi.size(); ++k)
        p[k] = std::max(std::min(m * usable(phi[k]) / total, 1.0), min_probability);
    return p;
}

}  // namespace render
