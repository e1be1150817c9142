#include "tests/support/chi_square.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <vector>

#include "core/math/constants.h"

namespace render::testing {
namespace {

// Series for P(a, x), valid for x < a + 1 (Numerical Recipes, section 6.2).
double gamma_p_series(double a, double x) {
    double sum = 1.0 / a, term = sum;
    for (int n = 1; n < 10000; ++n) {
        term *= x / (a + n);
        sum += term;
        if (std::abs(term) < std::abs(sum) * 1e-15) break;
    }
    return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Continued fraction for Q(a, x), valid for x >= a + 1 (modified Lentz).
double gamma_q_fraction(double a, double x) {
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::abs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::abs(c) < tiny) c = tiny;
        d = 1.0 / d;
        double delta = d * c;
        h *= delta;
        if (std::abs(delta - 1.0) < 1e-15) break;
    }
    return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

// Integral of pdf over [x0,x1]x[y0,y1] by composite 2-point Gauss-Legendre on n x n sub-cells.
// All nodes are interior: a density that jumps at a cell edge (hemisphere rims, cones,
// piecewise-constant distributions) is integrated without the bias of edge nodes.
double integrate_cell(const std::function<double(Vec2)>& pdf, double x0, double x1, double y0,
                      double y1, int n) {
    const double node = 0.5 / std::sqrt(3.0);  // Gauss-Legendre nodes at 1/2 -+ node
    double hx = (x1 - x0) / n, hy = (y1 - y0) / n, sum = 0;
    for (int i = 0; i < n; ++i)
        for (int a = -1; a <= 1; a += 2) {
            double x = x0 + (i + 0.5 + a * node) * hx;
            for (int j = 0; j < n; ++j)
                for (int b = -1; b <= 1; b += 2) {
                    double y = y0 + (j + 0.5 + b * node) * hy;
                    double v = pdf(Vec2(float(x), float(y)));
                    sum += std::isfinite(v) ? v : 0.0;
                }
        }
    return sum * hx * hy / 4.0;
}

}  // namespace

double regularized_gamma_q(double a, double x) {
    if (x <= 0) return 1.0;
    if (x < a + 1.0) return 1.0 - gamma_p_series(a, x);
    return gamma_q_fraction(a, x);
}

ChiSquareResult chi_square_test_2d(const std::function<std::optional<Vec2>(Rng&)>& sample,
                                   const std::function<double(Vec2)>& pdf, Rect domain,
                                   const ChiSquareOptions& options) {
    const int nx = options.resolution_x, ny = options.resolution_y;
    const int cells = nx * ny;
    std::vector<double> observed(cells, 0.0), expected(cells, 0.0);

    Rng rng(StreamKey{options.seed, 0, 1, 0});
    for (int i = 0; i < options.sample_count; ++i) {
        std::optional<Vec2> p = sample(rng);
        if (!p) continue;
        double fx = (p->x - domain.x0) / (domain.x1 - domain.x0);
        double fy = (p->y - domain.y0) / (domain.y1 - domain.y0);
        int cx = std::clamp(int(fx * nx), 0, nx - 1);
        int cy = std::clamp(int(fy * ny), 0, ny - 1);
        observed[cy * nx + cx] += 1.0;
    }

    ChiSquareResult result;
    double dx = (domain.x1 - domain.x0) / nx, dy = (domain.y1 - domain.y0) / ny;
    for (int cy = 0; cy < ny; ++cy)
        for (int cx = 0; cx < nx; ++cx) {
            double integral = integrate_cell(pdf, domain.x0 + cx * dx, domain.x0 + (cx + 1) * dx,
                                             domain.y0 + cy * dy, domain.y0 + (cy + 1) * dy, 8);
            result.pdf_integral += integral;
            expected[cy * nx + cx] = integral * options.sample_count;
        }

    // Sort cells by expected count and pool the smallest until each group has >= 5.
    std::vector<int> order(cells);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
    double pooled_obs = 0, pooled_exp = 0, stat = 0;
    int groups = 0;
    struct Worst {
        int cell;
        double obs, exp, contribution;
    };
    std::vector<Worst> worst;
    for (int idx : order) {
        if (expected[idx] == 0) {
            // A sample where the pdf is zero: the sampler and pdf disagree outright.
            if (observed[idx] > 0) {
                result.passed = false;
                std::ostringstream msg;
                msg << "cell " << idx << " (x " << idx % nx << ", y " << idx / nx << ") got "
                    << observed[idx] << " samples but the pdf integrates to 0 there";
                result.message = msg.str();
                return result;
            }
            continue;
        }
        if (pooled_exp + expected[idx] < 5.0) {
            pooled_obs += observed[idx];
            pooled_exp += expected[idx];
            continue;
        }
        double o = observed[idx] + pooled_obs, e = expected[idx] + pooled_exp;
        pooled_obs = pooled_exp = 0;
        double c = (o - e) * (o - e) / e;
        stat += c;
        ++groups;
        worst.push_back({idx, o, e, c});
    }
    if (pooled_exp > 0) {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        ++groups;
    }
    result.statistic = stat;
    result.degrees_of_freedom = std::max(1, groups - 1);
    result.p_value = regularized_gamma_q(0.5 * result.degrees_of_freedom, 0.5 * stat);
    double alpha = 1.0 - std::pow(1.0 - options.significance, 1.0 / options.test_count);
    result.passed = result.p_value >= alpha;

    std::sort(worst.begin(), worst.end(),
              [](const Worst& a, const Worst& b) { return a.contribution > b.contribution; });
    std::ostringstream msg;
    msg << "chi2 = " << stat << ", dof = " << result.degrees_of_freedom
        << ", p = " << result.p_value << " (alpha = " << alpha
        << "), pdf integral = " << result.pdf_integral << "; worst cells:";
    for (size_t i = 0; i < std::min<size_t>(5, worst.size()); ++i)
        msg << " [x " << worst[i].cell % nx << ", y " << worst[i].cell / nx << ": observed "
            << worst[i].obs << ", expected " << worst[i].exp << "]";
    result.message = msg.str();
    return result;
}

ChiSquareResult chi_square_test_sphere(const std::function<std::optional<Vec3>(Rng&)>& sample,
                                       const std::function<double(const Vec3&)>& pdf,
                                       const ChiSquareOptions& options) {
    // (phi, z) with phi in [0, 2 pi), z = cos theta in [-1, 1]: d omega = d phi d z.
    auto to_direction = [](Vec2 p) {
        float z = std::clamp(p.y, -1.0f, 1.0f);
        float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        return Vec3(r * std::cos(p.x), r * std::sin(p.x), z);
    };
    auto sample_2d = [&](Rng& rng) -> std::optional<Vec2> {
        std::optional<Vec3> w = sample(rng);
        if (!w) return std::nullopt;
        float phi = std::atan2(w->y, w->x);
        if (phi < 0) phi += 2.0f * kPi;
        return Vec2(phi, w->z);
    };
    auto pdf_2d = [&](Vec2 p) { return pdf(to_direction(p)); };
    return chi_square_test_2d(sample_2d, pdf_2d, Rect{0.0, 2.0 * M_PI, -1.0, 1.0}, options);
}

}  // namespace render::testing
