#pragma once

// Integrators render one progressive iteration at a time. An iteration adds exactly one
// estimate per pixel to the target buffer, and takes all its random numbers from
// (seed, frame, iteration, stream) keys (core/sampling/rng.h), so the result does not depend
// on threads or on which worker runs it (DESIGN.md, the iteration contract).

#include <cstdint>
#include <memory>

#include "core/base/render_stats.h"
#include "core/image/image.h"
#include "core/image/technique_layers.h"
#include "core/math/ray.h"
#include "core/sampling/rng.h"
#include "core/scene/scene.h"

namespace render {

struct IterationKey {
    uint64_t seed = 0;
    uint32_t frame = 0;
    uint64_t iteration = 1;  // 1-based global index
};

class Integrator {
  public:
    virtual ~Integrator() = default;
    // Adds iteration `key.iteration`'s image to `target` (same size as the camera) and, if
    // `layers` is not null, each contribution to its technique's layer.
    virtual void render_iteration(const Scene& scene, const IterationKey& key,
                                  AccumulationBuffer& target, TechniqueLayers* layers,
                                  RenderStats& stats) const = 0;

    // Adaptive sampling (docs/reference/adaptive-sampling.md): whether the next iterations can
    // estimate only the pixels whose entry of set_active_pixels is 1, leaving every other pixel
    // 0 and every active pixel's value that of an iteration without the mask.
    virtual bool takes_active_pixels() const { return false; }
    // One entry per pixel (the caller keeps it alive); nullptr: every pixel.
    void set_active_pixels(const uint8_t* active) { active_ = active; }

  protected:
    const uint8_t* active_pixels() const { return active_; }

  private:
    const uint8_t* active_ = nullptr;
};

// Integrators that estimate each pixel independently from one camera ray (PT, eyelight).
// Handles tiling, threading, per-pixel random streams and dropping non-finite samples.
class PixelIntegrator : public Integrator {
  public:
    void render_iteration(const Scene& scene, const IterationKey& key, AccumulationBuffer& target,
                          TechniqueLayers* layers, RenderStats& stats) const override;
    // Each pixel is its own stream's estimate: skipping one changes no other.
    bool takes_active_pixels() const override { return true; }

  protected:
    // Radiance arriving along `ray` (a camera ray). Counts the rays it traces in stats and
    // reports each technique's contribution to `sink`.
    virtual Rgb Li(const Scene& scene, const Ray& ray, Rng& rng, RenderStats& stats,
                   const LayerSink& sink) const = 0;
};

}  // namespace render
