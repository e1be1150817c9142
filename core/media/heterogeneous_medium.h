#pragma once

// A medium whose coefficients vary in space (Mitsuba 3's `heterogeneous`):
//     sigma_t(p) = scale * sigma_t_volume(p),   sigma_s(p) = sigma_t(p) * albedo_volume(p).
// Outside the extinction volume's bounds the medium is empty (sigma_t = 0).
//
// Distances: delta tracking against the piecewise-constant majorant of a MajorantGrid, with
// *spectral tracking* (Kutz, Habel, Li and Novak 2017, "Spectral and Decomposition Tracking for
// Rendering Heterogeneous Volumes") for RGB extinction. Transmittance: ratio tracking over the
// same grid with Russian roulette. See sample() and transmittance() for the estimators and
// docs/design/media.md for their weight bounds.

#include <array>
#include <memory>

#include "core/media/majorant_grid.h"
#include "core/media/medium.h"
#include "core/media/volume.h"

namespace render {

class HeterogeneousMedium final : public Medium {
  public:
    // `albedo` must lie in [0, 1]. `majorant_resolution` {0, 0, 0} chooses the default (one
    // majorant cell per 8 voxels of sigma_t). `radiance` (may be null: no emission) is the
    // emitted radiance L_e(p); the source term is sigma_a(p) L_e(p) with
    // sigma_a = sigma_t (1 - albedo), so emission lives only where the medium absorbs.
    HeterogeneousMedium(std::shared_ptr<const Volume> sigma_t, std::shared_ptr<const Volume> albedo,
                        float scale, std::shared_ptr<const PhaseFunction> phase,
                        std::array<int, 3> majorant_resolution = {0, 0, 0},
                        std::shared_ptr<const Volume> radiance = nullptr);

    // Spectral tracking. Let mu be the cell's scalar majorant (>= every channel of sigma_t)
    // and w the weight carried since the start of this call (w = (1, 1, 1) at the start). At a
    // tentative collision (density mu) with sigma_n = mu - sigma_t, the event is real with
    // probability P_r = avg(w sigma_t) / (avg(w sigma_t) + avg(w sigma_n)) and null otherwise
    // (history-aware probabilities with the channel average; absorption is not an event, it
    // goes into the weight). Real: scatter with weight w sigma_s / (mu P_r). Null: w <- w
    // sigma_n / (mu (1 - P_r)), and go on.
    //
    // Bounds: P_r + P_n = 1 gives avg(w) mu = avg(w sigma_t) + avg(w sigma_n), so a null
    // collision leaves avg(w) unchanged: avg(w) = 1 always, and since w >= 0 every channel of w
    // is <= 3. A scattering weight is w[c] albedo[c] sigma_t[c] / avg(w sigma_t)
    // <= 3 albedo[c]. So every weight is <= 3 albedo (scattering) or <= 3 (passing through),
    // the same bounds as the homogeneous medium's spectral MIS, however different the channels.
    // For grey sigma_t, w stays (1, 1, 1): classic delta tracking (P_r = sigma_t / mu, weight
    // albedo on scattering, exactly 1 on passing).
    //
    // Emission (emissive media only): at every tentative collision reached, before the
    // real/null choice, emission += w sigma_a L_e / mu. A collision at t is reached with only
    // null events before it with probability prod (1 - P_r), and w = prod sigma_n / (mu (1 -
    // P_r)), so E[w; reached] = E[prod sigma_n / mu] = T(0, t) (ratio tracking's identity);
    // the collisions form a Poisson process of rate mu, so the sum's mean is
    // integral T sigma_a L_e ds over (0, t_max) (docs/design/media.md, "Emission in media").
    MediumSample sample(const Ray& ray, float t_max, Rng& rng) const override;

    // Ratio tracking: T *= 1 - sigma_t / mu at each tentative collision. Once max(T) < 0.1 the
    // walk survives with probability max(T) and T /= max(T) (Russian roulette, unbiased); the
    // estimate always lies in [0, 1].
    Rgb transmittance(const Ray& ray, float t_max, Rng& rng) const override;

    // The smooth approximation allowed by medium.h: the homogeneous formulas with the optical
    // depth tau(t) estimated deterministically by the midpoint rule on each majorant cell the
    // ray crosses (one density look-up per cell): pdf_scatter_l = avg(sigma_t(t) exp(-tau(t))),
    // probability_pass = avg(exp(-tau(t))). Exact for constant volumes.
    float pdf_scatter_l(const Ray& ray, float t) const override;
    float probability_pass(const Ray& ray, float t) const override;
    // One optical-depth estimate for all three densities.
    PieceDensities piece_densities(const Ray& ray, float t, bool at_start) const override;

    Rgb sigma_s(const Vec3& p) const override;
    Rgb sigma_t(const Vec3& p) const override { return sigma_t_->eval(p) * scale_; }
    const PhaseFunction& phase() const override { return *phase_; }
    bool is_homogeneous() const override { return false; }
    // Grey extinction: classic delta tracking, whose pass weight is exactly 1 (sample()).
    bool pass_weight_is_one() const override { return grey_; }
    // sample()'s walk replayed from its random state up to t (the same draws: the emission
    // estimate draws nothing), returning its weight on passing t.
    Rgb replay_pass_weight(const Ray& ray, float t_max, float t, Rng rng) const override;
    bool is_emissive() const override { return radiance_ != nullptr; }
    Rgb radiance(const Vec3& p) const override {
        return radiance_ ? radiance_->eval(p) : Rgb(0.0f);
    }
    std::string to_string() const override;

    const MajorantGrid& majorant_grid() const { return majorants_; }

    // Russian roulette threshold of transmittance().
    static constexpr float kRouletteThreshold = 0.1f;

  private:
    template <typename Visit>
    void for_each_tentative_collision(const Ray& ray, float t_max, Rng& rng, Visit&& visit) const;

    Rgb optical_depth(const Ray& ray, float t) const;

    std::shared_ptr<const Volume> sigma_t_, albedo_, radiance_;
    float scale_;
    std::shared_ptr<const PhaseFunction> phase_;
    MajorantGrid majorants_;
    bool grey_;  // one-channel extinction: classic delta tracking
};

}  // namespace render
