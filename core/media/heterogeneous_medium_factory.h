#pragma once

#include <memory>

#include "core/base/properties.h"
#include "core/media/medium.h"
#include "core/media/volume.h"

namespace render {

// Mitsuba 3's `heterogeneous` medium from its parsed volumes: reads `scale` (float, default 1,
// finite and >= 0) and accepts `sample_emitters` and `has_spectral_extinction` (booleans, no
// effect). A null sigma_t, albedo or phase gets Mitsuba 3's default: constant 1, constant 0.75,
// isotropic. The albedo must lie in [0, 1]; scale * max(sigma_t) must be finite. `radiance`
// (null: none) is the emitted radiance L_e (docs/design/media.md, "Emission in media"): finite and
// >= 0; a volume that is zero everywhere is no emission.
std::unique_ptr<Medium> make_heterogeneous_medium(const Properties& props,
                                                  std::shared_ptr<const Volume> sigma_t,
                                                  std::shared_ptr<const Volume> albedo,
                                                  std::shared_ptr<const PhaseFunction> phase,
                                                  std::shared_ptr<const Volume> radiance = nullptr);

}  // namespace render
