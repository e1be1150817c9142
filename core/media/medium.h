#pragma once

// Participating media. A medium fills the space between surfaces that name it as their interior
// or exterior (Mitsuba's medium interfaces); paths carry the medium they are in and change it
// at the surfaces that declare media (core/media/medium_interface.h).
//
// Coefficients are RGB. Distances are sampled with *spectral MIS* (one-sample MIS over the three
// channels with the balance heuristic, as in pbrt-v4 and Mitsuba 3): a channel c is chosen
// uniformly, the distance is sampled with sigma_t[c], and the weight divides by the average of
// the three channels' densities. Every channel's weight is then bounded, by 3 * albedo for a
// scattering event and 3 for passing through, however different the channels' coefficients are
// (sampling with one channel only makes the others' weights unbounded: colour noise). Choosing
// the channel uniformly, not by throughput, keeps the density a property of the segment alone,
// which is what bidirectional MIS needs (the density is the same from either end).

#include <cmath>
#include <string>

#include "core/math/ray.h"
#include "core/math/vec.h"
#include "core/media/phase_function.h"
#include "core/sampling/rng.h"

namespace render {

struct MediumSample {
    // True for a real scattering event at distance t; false when the ray passed through to the
    // end of the segment (t = t_max), where a surface interaction (or nothing) awaits.
    bool scattered = false;
    float t = 0;
    // Factor for the path throughput: T(t) * sigma_s(t) / p(t) for a scattering event,
    // T(t_max) / P(pass) otherwise. Absorption is part of the weight, never a termination, so
    // the weight may be zero.
    Rgb weight{1.0f};
    // Emission (docs/design/media.md, "Emission in media"): an unbiased estimate of the radiance
    // that the medium emits toward the ray origin from (0, t_max),
    //     integral_0^t_max T(0, s) sigma_a(s) L_e(s) ds,
    // to be multiplied by the throughput *before* `weight`. Zero unless is_emissive().
    Rgb emission{0.0f};
    // For a scattering event: the factor of a source term at t, `weight` without sigma_s(t)
    // (weight = source_weight * sigma_s(t)). The bidirectional family's collision estimator of
    // emission multiplies it by sigma_a(t) L_e(t) (docs/design/media.md, "Emitting media as
    // lights").
    Rgb source_weight{0.0f};
};

class Medium {
  public:
    virtual ~Medium() = default;

    // Samples the next real interaction along `ray` (unit direction) in (0, t_max); t_max may
    // be infinite (a ray leaving the scene in an unbounded medium).
    virtual MediumSample sample(const Ray& ray, float t_max, Rng& rng) const = 0;

    // Transmittance along `ray` over (0, t_max): exact for homogeneous media, an unbiased
    // estimate (ratio tracking) for heterogeneous ones.
    virtual Rgb transmittance(const Ray& ray, float t_max, Rng& rng) const = 0;

    // Densities of sample()'s distance sampling, for MIS: per unit length of a scattering event
    // at t (pdf_scatter_l), and the probability of passing beyond t. Exact for homogeneous
    // media. Heterogeneous media return a smooth approximation (weights built from it still sum
    // to one, so MIS stays unbiased; only its variance reduction is approximate).
    virtual float pdf_scatter_l(const Ray& ray, float t) const = 0;
    virtual float probability_pass(const Ray& ray, float t) const = 0;

    // The densities of one piece of length t along `ray` that bidirectional MIS needs
    // (medium_segment.h): passing it, a scattering event at its end and, when `at_start`, a
    // scattering event at its start sampled from the far end (sigma_t at the start, the same
    // optical depth; 0 when not asked for). The default calls the two functions above;
    // heterogeneous media override it to estimate the optical depth once.
    struct PieceDensities {
        float pass = 1, scatter_at_end = 0, scatter_at_start = 0;
    };
    virtual PieceDensities piece_densities(const Ray& ray, float t, bool at_start) const {
        PieceDensities d{probability_pass(ray, t), pdf_scatter_l(ray, t), 0.0f};
        if (at_start)
            d.scatter_at_start = std::isfinite(t) ? pdf_scatter_l(Ray(ray.at(t), -ray.direction), t)
                                                  : d.scatter_at_end;
        return d;
    }

    // Local coefficients, per unit length.
    virtual Rgb sigma_s(const Vec3& p) const = 0;
    virtual Rgb sigma_t(const Vec3& p) const = 0;

    virtual const PhaseFunction& phase() const = 0;
    virtual bool is_homogeneous() const = 0;
    // True when sample()'s weight on passing any distance is exactly 1 in every channel, i.e.
    // the probability of passing t is the transmittance T(t) itself (grey extinction sampled by
    // delta tracking). upbp's short photon beams, cut at a sampled distance, then need no
    // transmittance estimate along the beam: T(t) / P(pass t) = 1 (docs/design/media.md).
    virtual bool pass_weight_is_one() const { return false; }
    // For media whose pass weight is neither one nor in closed form (chromatic grids): the
    // weight w(t) with which sample(ray, t_max, rng), started with this random state, passed t
    // (zero if it stopped before t). E[w(t) 1{passed t}] = T(t) per channel, so a short photon
    // beam cut where that walk stopped carries w(t) at t (docs/design/media.md, "Photon beams in
    // grid media"). Media that never need it return one.
    virtual Rgb replay_pass_weight(const Ray&, float /*t_max*/, float /*t*/, Rng /*rng*/) const {
        return Rgb(1.0f);
    }
    // True when the medium emits (a non-zero `radiance`): sample() then fills
    // MediumSample::emission. Non-emissive media do no emission work at all.
    virtual bool is_emissive() const { return false; }
    // Emitted radiance L_e(p) (the source term is sigma_a(p) L_e(p)); zero by default.
    virtual Rgb radiance(const Vec3&) const { return Rgb(0.0f); }
    virtual std::string to_string() const = 0;
};

}  // namespace render
