#include "core/media/heterogeneous_medium_factory.h"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/media/constant_volume.h"
#include "core/media/heterogeneous_medium.h"
#include "core/media/isotropic_phase.h"

namespace render {

namespace {
constexpr double kMaxGridOpticalDepth = 1e5;
}  // namespace

std::unique_ptr<Medium> make_heterogeneous_medium(const Properties& props,
                                                  std::shared_ptr<const Volume> sigma_t,
                                                  std::shared_ptr<const Volume> albedo,
                                                  std::shared_ptr<const PhaseFunction> phase,
                                                  std::shared_ptr<const Volume> radiance) {
    const float scale = props.get_float("scale", 1.0f);
    if (!(std::isfinite(scale) && scale >= 0))
        throw props.error("scale", "must be finite and >= 0");
    props.get_bool("sample_emitters", true);          // accepted: NEE is always used
    props.get_bool("has_spectral_extinction", true);  // accepted: coefficients are RGB
    if (!sigma_t) sigma_t = std::make_shared<ConstantVolume>(Rgb(1.0f));
    if (!albedo) albedo = std::make_shared<ConstantVolume>(Rgb(0.75f));
    if (!phase) phase = std::make_shared<IsotropicPhase>();
    const float max_sigma = sigma_t->max_value();
    if (!(std::isfinite(max_sigma) && max_sigma >= 0))
        throw props.error("sigma_t", "must be finite and >= 0");
    if (!std::isfinite(scale * max_sigma))
        throw props.error("scale", "the scaled extinction overflows");
    // Delta and ratio tracking take about one step per majorant mean free path, so a grid many
    // mean free paths across would keep a worker busy for ever on one ray. Beyond
    // kMaxGridOpticalDepth (e^-1e5 transmittance: opaque) the scene is refused.
    const Aabb b = sigma_t->bounds();
    if (!b.empty()) {
        const Vec3 d = b.hi - b.lo;
        const double depth = double(scale) * max_sigma * std::sqrt(double(dot(d, d)));
        if (std::isfinite(depth) && depth > kMaxGridOpticalDepth) {
            std::ostringstream what;
            what << "the grid is " << std::setprecision(3) << depth
                 << " mean free paths across at its densest, more than the 1e5 that tracking can "
                    "step through (a medium that dense is opaque: use a surface)";
            throw props.error("scale", what.str());
        }
    }
    const float max_albedo = albedo->max_value();
    if (!(max_albedo >= 0 && max_albedo <= 1.0f))
        throw props.error("albedo",
                          "must be in [0, 1] (its maximum is " + std::to_string(max_albedo) + ")");
    if (radiance) {
        const float max_radiance = radiance->max_value();
        if (!(std::isfinite(max_radiance) && max_radiance >= 0))
            throw props.error("radiance", "must be finite and >= 0");
        if (max_radiance == 0) radiance = nullptr;  // no emission: no emission work
    }
    return std::make_unique<HeterogeneousMedium>(std::move(sigma_t), std::move(albedo), scale,
                                                 std::move(phase), std::array<int, 3>{0, 0, 0},
                                                 std::move(radiance));
}

}  // namespace render
