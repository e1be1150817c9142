#include "core/media/heterogeneous_medium.h"

#include <cmath>
#include <sstream>

namespace render {
namespace {

Rgb clamp_non_negative(const Rgb& c) {
    return Rgb(std::max(c.r, 0.0f), std::max(c.g, 0.0f), std::max(c.b, 0.0f));
}

// Distance to the next tentative collision with majorant mu; always moves t forward.
float advance(float t, float mu, Rng& rng) {
    const float next = t - std::log1p(-rng.next_1d()) / mu;
    return next > t ? next : std::nextafter(t, kInfinity);
}

}  // namespace

// Tentative collisions along the ray over (0, t_max): exponential steps with each majorant
// cell's rate, calling visit(t, majorant) at every one until visit returns false. Delta
// tracking and ratio tracking differ only in what they do at a collision.
template <typename Visit>
void HeterogeneousMedium::for_each_tentative_collision(const Ray& ray, float t_max, Rng& rng,
                                                       Visit&& visit) const {
    MajorantGrid::Iterator it = majorants_.traverse(ray, 0.0f, t_max);
    MajorantSegment seg;
    while (it.next(seg)) {
        const float mu = seg.majorant;
        if (!(mu > 0)) continue;
        for (float t = advance(seg.t0, mu, rng); t < seg.t1; t = advance(t, mu, rng))
            if (!visit(t, mu)) return;
    }
}

HeterogeneousMedium::HeterogeneousMedium(std::shared_ptr<const Volume> sigma_t,
                                         std::shared_ptr<const Volume> albedo, float scale,
                                         std::shared_ptr<const PhaseFunction> phase,
                                         std::array<int, 3> majorant_resolution,
                                         std::shared_ptr<const Volume> radiance)
    : sigma_t_(std::move(sigma_t)),
      albedo_(std::move(albedo)),
      radiance_(std::move(radiance)),
      scale_(scale),
      phase_(std::move(phase)),
      majorants_(*sigma_t_, scale_, majorant_resolution),
      grey_(sigma_t_->channels() == 1) {}

Rgb HeterogeneousMedium::sigma_s(const Vec3& p) const {
    return sigma_t(p) * albedo_->eval(p);
}

MediumSample HeterogeneousMedium::sample(const Ray& ray, float t_max, Rng& rng) const {
    MediumSample s;
    s.t = t_max;
    Rgb w(1.0f);
    for_each_tentative_collision(ray, t_max, rng, [&](float t, float mu) {
        const Vec3 p = ray.at(t);
        const Rgb st = sigma_t(p);
        if (radiance_) {
            // sigma_a L_e / mu with the weight w carried to this collision (header comment).
            const Rgb le = radiance_->eval(p);
            if (!le.is_black())
                s.emission += w * st * (Rgb(1.0f) - albedo_->eval(p)) * le * (1.0f / mu);
        }
        if (grey_) {
            // Classic delta tracking, the exact grey case of the estimator below (where
            // w stays (1, 1, 1)): no rounding from the general weights.
            if (!(rng.next_1d() * mu < st.r)) return true;
            s.scattered = true;
            s.t = t;
            s.weight = albedo_->eval(p);
            s.source_weight = Rgb(1.0f / st.r);
            return false;
        }
        // sigma_n >= 0 when the majorant bounds the density (majorant_grid.h).
        const Rgb sn = clamp_non_negative(Rgb(mu) - st);
        const float real = (w * st).average(), null = (w * sn).average();
        const float total = real + null;
        if (!(total > 0)) {  // w = 0: nothing left to estimate
            w = Rgb(0.0f);
            return false;
        }
        if (rng.next_1d() * total < real) {
            s.scattered = true;
            s.t = t;
            // w sigma_s / (mu P_r) with P_r = real / total.
            s.weight = w * st * albedo_->eval(p) * (total / (mu * real));
            s.source_weight = w * (total / (mu * real));
            return false;
        }
        w = w * sn * (total / (mu * null));
        return true;
    });
    if (!s.scattered) s.weight = w;
    return s;
}

Rgb HeterogeneousMedium::replay_pass_weight(const Ray& ray, float t_max, float t, Rng rng) const {
    Rgb w(1.0f);
    bool passed = true;
    // The branches and draws of sample(), in the same order, stopping at t.
    for_each_tentative_collision(ray, t_max, rng, [&](float ti, float mu) {
        if (!(ti < t)) return false;
        const Rgb st = sigma_t(ray.at(ti));
        if (grey_) {
            if (!(rng.next_1d() * mu < st.r)) return true;
            passed = false;
            return false;
        }
        const Rgb sn = clamp_non_negative(Rgb(mu) - st);
        const float real = (w * st).average(), null = (w * sn).average();
        const float total = real + null;
        if (!(total > 0)) {
            w = Rgb(0.0f);
            return false;
        }
        if (rng.next_1d() * total < real) {
            passed = false;
            return false;
        }
        w = w * sn * (total / (mu * null));
        return true;
    });
    return passed ? w : Rgb(0.0f);
}

Rgb HeterogeneousMedium::transmittance(const Ray& ray, float t_max, Rng& rng) const {
    Rgb tr(1.0f);
    for_each_tentative_collision(ray, t_max, rng, [&](float t, float mu) {
        tr = tr * clamp_non_negative(Rgb(1.0f) - sigma_t(ray.at(t)) / mu);
        const float m = tr.max();
        if (!(m > 0)) {
            tr = Rgb(0.0f);
            return false;
        }
        if (m < kRouletteThreshold) {
            if (rng.next_1d() >= m) {
                tr = Rgb(0.0f);
                return false;
            }
            tr = tr / m;
        }
        return true;
    });
    return tr;
}

Rgb HeterogeneousMedium::optical_depth(const Ray& ray, float t) const {
    Rgb tau(0.0f);
    MajorantGrid::Iterator it = majorants_.traverse(ray, 0.0f, t);
    MajorantSegment seg;
    while (it.next(seg)) {
        if (!(seg.majorant > 0) || !(seg.t1 > seg.t0)) continue;
        if (std::isinf(seg.t1)) {
            // An unbounded (constant) volume: the density is the same everywhere.
            const Rgb st = sigma_t(ray.at(seg.t0));
            for (int c = 0; c < 3; ++c) tau[c] += st[c] > 0 ? kInfinity : 0.0f;
            continue;
        }
        tau += sigma_t(ray.at(0.5f * (seg.t0 + seg.t1))) * (seg.t1 - seg.t0);
    }
    return tau;
}

float HeterogeneousMedium::pdf_scatter_l(const Ray& ray, float t) const {
    const Rgb tau = optical_depth(ray, t), st = sigma_t(ray.at(t));
    Rgb pdf;
    for (int c = 0; c < 3; ++c) pdf[c] = st[c] > 0 ? st[c] * std::exp(-tau[c]) : 0.0f;
    return pdf.average();
}

Medium::PieceDensities HeterogeneousMedium::piece_densities(const Ray& ray, float t,
                                                            bool at_start) const {
    const Rgb tau = optical_depth(ray, t);
    const Rgb pass(std::exp(-tau.r), std::exp(-tau.g), std::exp(-tau.b));
    auto scatter_at = [&](const Vec3& p) {
        const Rgb st = sigma_t(p);
        Rgb pdf;
        for (int c = 0; c < 3; ++c) pdf[c] = st[c] > 0 ? st[c] * pass[c] : 0.0f;
        return pdf.average();
    };
    PieceDensities d{pass.average(), scatter_at(ray.at(t)), 0.0f};
    if (at_start) d.scatter_at_start = std::isfinite(t) ? scatter_at(ray.origin) : d.scatter_at_end;
    return d;
}

float HeterogeneousMedium::probability_pass(const Ray& ray, float t) const {
    const Rgb tau = optical_depth(ray, t);
    return Rgb(std::exp(-tau.r), std::exp(-tau.g), std::exp(-tau.b)).average();
}

std::string HeterogeneousMedium::to_string() const {
    std::ostringstream os;
    const std::array<int, 3> r = majorants_.resolution();
    os << "heterogeneous(sigma_t=" << sigma_t_->to_string() << ", albedo=" << albedo_->to_string()
       << ", scale=" << scale_ << ", majorant grid " << r[0] << "x" << r[1] << "x" << r[2]
       << ", phase=" << phase_->to_string();
    if (radiance_) os << ", radiance=" << radiance_->to_string();
    os << ")";
    return os.str();
}

}  // namespace render
