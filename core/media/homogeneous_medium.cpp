#include "core/media/homogeneous_medium.h"

#include <cmath>
#include <sstream>

namespace render {

HomogeneousMedium::HomogeneousMedium(const Rgb& sigma_a, const Rgb& sigma_s,
                                     std::shared_ptr<const PhaseFunction> phase,
                                     const Rgb& radiance)
    : sigma_s_(sigma_s),
      sigma_t_(sigma_a + sigma_s),
      radiance_(radiance),
      emissive_(!(sigma_a * radiance).is_black()),
      phase_(std::move(phase)) {}

Rgb HomogeneousMedium::emission(float t_max) const {
    const Rgb sigma_a = sigma_t_ - sigma_s_;
    Rgb e;
    for (int c = 0; c < 3; ++c) {
        const float source = std::max(sigma_a[c], 0.0f) * radiance_[c];
        if (!(source > 0)) {
            e[c] = 0.0f;
            continue;
        }
        // (1 - exp(-sigma_t t)) / sigma_t, by expm1 so that optically thin segments keep
        // their precision; sigma_t >= sigma_a > 0 here.
        const float s = sigma_t_[c];
        e[c] = source * (std::isinf(t_max) ? 1.0f / s : -std::expm1(-s * t_max) / s);
    }
    return e;
}

Rgb HomogeneousMedium::transmittance(float t) const {
    Rgb tr;
    for (int c = 0; c < 3; ++c)
        tr[c] = sigma_t_[c] == 0 ? 1.0f : (std::isinf(t) ? 0.0f : std::exp(-sigma_t_[c] * t));
    return tr;
}

MediumSample HomogeneousMedium::sample(const Ray&, float t_max, Rng& rng) const {
    // Spectral MIS (medium.h): sample with one channel, weight by the average density.
    const int channel = std::min(int(rng.next_1d() * 3.0f), 2);
    const float u = rng.next_1d();
    const float sigma = sigma_t_[channel];
    const float t = sigma > 0 ? -std::log1p(-u) / sigma : kInfinity;
    MediumSample s;
    if (t < t_max) {
        const Rgb tr = transmittance(t);
        const float pdf = (sigma_t_ * tr).average();
        s.scattered = true;
        s.t = t;
        s.source_weight = pdf > 0 ? tr / pdf : Rgb(0.0f);
        s.weight = pdf > 0 ? sigma_s_ * tr / pdf : Rgb(0.0f);
    } else {
        const Rgb tr = transmittance(t_max);
        const float probability = tr.average();
        s.t = t_max;
        s.weight = probability > 0 ? tr / probability : Rgb(0.0f);
    }
    if (emissive_) s.emission = emission(t_max);
    return s;
}

Rgb HomogeneousMedium::transmittance(const Ray&, float t_max, Rng&) const {
    return transmittance(t_max);
}

float HomogeneousMedium::pdf_scatter_l(const Ray&, float t) const {
    return (sigma_t_ * transmittance(t)).average();
}

float HomogeneousMedium::probability_pass(const Ray&, float t) const {
    return transmittance(t).average();
}

std::string HomogeneousMedium::to_string() const {
    std::ostringstream os;
    os << "homogeneous(sigma_t=" << sigma_t_ << ", sigma_s=" << sigma_s_
       << ", phase=" << phase_->to_string();
    if (emissive_) os << ", radiance=" << radiance_;
    os << ")";
    return os.str();
}

}  // namespace render
