#include "tests/support/chi_square.h"

#include <gtest/gtest.h>

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

// "Prefix/Suite.Name/param" -> "Suite.Name": how a parameterised test is declared.
std::string without_parameters(const std::string& full_name) {
    size_t dot = full_name.find('.');
    if (dot == std::string::npos) return full_name;
    std::string suite = full_name.substr(0, dot), name = full_name.substr(dot + 1);
    if (size_t slash = suite.rfind('/'); slash != std::string::npos) suite.erase(0, slash + 1);
    if (size_t slash = name.find('/'); slash != std::string::npos) name.erase(slash);
    return suite + "." + name;
}

std::string current_test_name() {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    if (info == nullptr) return "";
    return std::string(info->test_suite_name()) + "." + info->name();
}

}  // namespace

// Fails a test that ends with fewer checks than it declared. OnTestEnd runs while the test is
// still gtest's current test (listeners appended later are told first, before the result
// printer), so the failure is the test's own.
class ChiSquareFamily::Listener final : public ::testing::EmptyTestEventListener {
  public:
    explicit Listener(ChiSquareFamily* family) : family_(family) {}
    // Every run of a test starts counting afresh (--gtest_repeat runs a test several times).
    void OnTestStart(const ::testing::TestInfo& info) override { family_->ran_.erase(name(info)); }
    void OnTestEnd(const ::testing::TestInfo& info) override {
        if (std::optional<std::string> error = family_->unfinished(name(info)))
            ADD_FAILURE() << *error;
    }

  private:
    static std::string name(const ::testing::TestInfo& info) {
        return std::string(info.test_suite_name()) + "." + info.name();
    }
    ChiSquareFamily* family_;
};

ChiSquareFamily::ChiSquareFamily(double significance) : significance_(significance) {
    listener_ = new Listener(this);
    ::testing::UnitTest::GetInstance()->listeners().Append(listener_);  // gtest owns it
}

ChiSquareFamily::~ChiSquareFamily() {
    delete ::testing::UnitTest::GetInstance()->listeners().Release(listener_);
}

void ChiSquareFamily::declare(const std::string& test, int checks, int instances) {
    declared_[test] += checks;
    total_ += checks * instances;
}

double ChiSquareFamily::alpha() const {
    if (total_ <= 0) return significance_;
    return 1.0 - std::pow(1.0 - significance_, 1.0 / total_);
}

int ChiSquareFamily::declared(const std::string& full_name) const {
    if (auto it = declared_.find(full_name); it != declared_.end()) return it->second;
    if (auto it = declared_.find(without_parameters(full_name)); it != declared_.end())
        return it->second;
    return 0;
}

std::optional<std::string> ChiSquareFamily::record_check() {
    const std::string name = current_test_name();
    if (name.empty()) return "a chi-square check outside any test";
    const int ran = ++ran_[name], allowed = declared(name);
    if (ran <= allowed) return std::nullopt;
    std::ostringstream msg;
    msg << name << " runs chi-square check " << ran << " but declared " << allowed
        << " (declare every check: CHI_SQUARE_TEST(family, Suite, Name, checks), "
           "tests/support/chi_square.h)";
    return msg.str();
}

std::optional<std::string> ChiSquareFamily::unfinished(const std::string& full_name) const {
    const int allowed = declared(full_name);
    auto it = ran_.find(full_name);
    const int ran = it == ran_.end() ? 0 : it->second;
    if (ran >= allowed) return std::nullopt;
    std::ostringstream msg;
    msg << full_name << " declared " << allowed << " chi-square checks but ran " << ran
        << " (the family's alpha assumes the declared count)";
    return msg.str();
}

double regularized_gamma_q(double a, double x) {
    if (x <= 0) return 1.0;
    if (x < a + 1.0) return 1.0 - gamma_p_series(a, x);
    return gamma_q_fraction(a, x);
}

ChiSquareResult chi_square_from_counts(ChiSquareFamily& family, const std::vector<double>& observed,
                                       const std::vector<double>& expected,
                                       const std::function<std::string(size_t)>& cell_name) {
    ChiSquareResult result;
    result.alpha = family.alpha();
    if (std::optional<std::string> error = family.record_check()) {
        ADD_FAILURE() << *error;
        result.message = *error;
        return result;
    }
    // Sort cells by expected count and pool the smallest until each group has >= 5.
    const size_t cells = expected.size();
    std::vector<size_t> order(cells);
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return expected[a] < expected[b]; });
    double pooled_obs = 0, pooled_exp = 0, stat = 0;
    int groups = 0;
    struct Worst {
        size_t cell;
        double obs, exp, contribution;
    };
    std::vector<Worst> worst;
    for (size_t idx : order) {
        if (expected[idx] == 0) {
            // A sample where the pdf is zero: the sampler and pdf disagree outright.
            if (observed[idx] > 0) {
                std::ostringstream msg;
                msg << "[" << cell_name(idx) << "] got " << observed[idx]
                    << " samples but the pdf integrates to 0 there";
                result.message = msg.str();
                return result;
            }
            continue;
        }
        pooled_obs += observed[idx];
        pooled_exp += expected[idx];
        if (pooled_exp < 5.0) continue;
        const double c = (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        stat += c;
        ++groups;
        worst.push_back({idx, pooled_obs, pooled_exp, c});
        pooled_obs = pooled_exp = 0;
    }
    if (pooled_exp > 0) {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        ++groups;
    }
    result.statistic = stat;
    result.degrees_of_freedom = std::max(1, groups - 1);
    result.p_value = regularized_gamma_q(0.5 * result.degrees_of_freedom, 0.5 * stat);
    result.passed = result.p_value >= result.alpha;

    std::sort(worst.begin(), worst.end(),
              [](const Worst& a, const Worst& b) { return a.contribution > b.contribution; });
    std::ostringstream msg;
    msg << "chi2 = " << stat << ", dof = " << result.degrees_of_freedom
        << ", p = " << result.p_value << " (alpha = " << result.alpha << ", family of "
        << family.total() << ")";
    msg << "; worst cells:";
    for (size_t i = 0; i < std::min<size_t>(5, worst.size()); ++i)
        msg << " [" << cell_name(worst[i].cell) << ": observed " << worst[i].obs << ", expected "
            << worst[i].exp << "]";
    result.message = msg.str();
    return result;
}

ChiSquareResult chi_square_test_discrete(ChiSquareFamily& family,
                                         const std::vector<double>& observed,
                                         const std::vector<double>& probability, int sample_count) {
    std::vector<double> expected(probability.size());
    double total = 0;
    for (size_t i = 0; i < probability.size(); ++i) {
        expected[i] = probability[i] * sample_count;
        total += probability[i];
    }
    ChiSquareResult result = chi_square_from_counts(family, observed, expected,
                                                    [](size_t i) { return std::to_string(i); });
    result.pdf_integral = total;
    if (!result.message.empty()) result.message += ", probability sum = " + std::to_string(total);
    return result;
}

ChiSquareResult chi_square_test_2d(ChiSquareFamily& family,
                                   const std::function<std::optional<Vec2>(Rng&)>& sample,
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

    double pdf_integral = 0;
    double dx = (domain.x1 - domain.x0) / nx, dy = (domain.y1 - domain.y0) / ny;
    for (int cy = 0; cy < ny; ++cy)
        for (int cx = 0; cx < nx; ++cx) {
            double integral = integrate_cell(pdf, domain.x0 + cx * dx, domain.x0 + (cx + 1) * dx,
                                             domain.y0 + cy * dy, domain.y0 + (cy + 1) * dy, 8);
            pdf_integral += integral;
            expected[cy * nx + cx] = integral * options.sample_count;
        }
    ChiSquareResult result = chi_square_from_counts(family, observed, expected, [nx](size_t i) {
        return "x " + std::to_string(i % nx) + ", y " + std::to_string(i / nx);
    });
    result.pdf_integral = pdf_integral;
    result.message += ", pdf integral = " + std::to_string(pdf_integral);
    return result;
}

ChiSquareResult chi_square_test_sphere(ChiSquareFamily& family,
                                       const std::function<std::optional<Vec3>(Rng&)>& sample,
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
    return chi_square_test_2d(family, sample_2d, pdf_2d, Rect{0.0, 2.0 * M_PI, -1.0, 1.0}, options);
}

double integrate_graded(const std::function<double(double)>& f, double a, double b,
                        std::optional<double> peak, double h) {
    std::vector<double> points = {a, b};
    if (peak && h > 0) {
        if (*peak > a && *peak < b) points.push_back(*peak);
        for (double d = h; d < 2.0 * (b - a) + std::abs(*peak - a) + std::abs(*peak - b); d *= 2)
            for (double p : {*peak - d, *peak + d})
                if (p > a && p < b) points.push_back(p);
    }
    std::sort(points.begin(), points.end());
    const double nodes[3] = {-std::sqrt(0.6), 0.0, std::sqrt(0.6)};
    const double weights[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    double sum = 0;
    for (size_t i = 0; i + 1 < points.size(); ++i) {
        const int pieces = 16;
        double x0 = points[i], hx = (points[i + 1] - points[i]) / pieces;
        for (int j = 0; j < pieces; ++j) {
            double mid = x0 + (j + 0.5) * hx;
            for (int q = 0; q < 3; ++q) {
                double v = f(mid + 0.5 * hx * nodes[q]);
                sum += std::isfinite(v) ? 0.5 * hx * weights[q] * v : 0.0;
            }
        }
    }
    return sum;
}

ChiSquareResult chi_square_test_1d(ChiSquareFamily& family,
                                   const std::function<double(Rng&)>& sample,
                                   const std::function<double(double)>& pdf, double x0, double x1,
                                   const ChiSquareOptions1d& options) {
    const int cells = options.cells;
    std::vector<double> observed(cells, 0.0), expected(cells, 0.0);
    Rng rng(StreamKey{options.seed, 0, 1, 0});
    std::optional<double> outside;
    for (int i = 0; i < options.sample_count && !outside; ++i) {
        double x = sample(rng);
        if (!(x >= x0 && x <= x1))
            outside = x;
        else
            observed[std::clamp(int((x - x0) / (x1 - x0) * cells), 0, cells - 1)] += 1;
    }
    if (outside) {
        // Still one check of the family: record it, then fail.
        ChiSquareResult result = chi_square_from_counts(family, {}, {}, {});
        result.passed = false;
        result.message = "sample " + std::to_string(*outside) + " outside the domain [" +
                         std::to_string(x0) + ", " + std::to_string(x1) + "]";
        return result;
    }
    const double w = (x1 - x0) / cells;
    double pdf_integral = 0;
    for (int c = 0; c < cells; ++c) {
        double integral =
            integrate_graded(pdf, x0 + c * w, x0 + (c + 1) * w, options.peak, options.h);
        pdf_integral += integral;
        expected[c] = integral * options.sample_count;
    }
    ChiSquareResult result = chi_square_from_counts(
        family, observed, expected, [](size_t i) { return "cell " + std::to_string(i); });
    result.pdf_integral = pdf_integral;
    result.message += ", pdf integral = " + std::to_string(pdf_integral);
    return result;
}

}  // namespace render::testing
