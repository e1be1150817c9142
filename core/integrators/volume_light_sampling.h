#pragma once

// Sampling the emitters of the bidirectional family: the scene's lights and its emitting media
// (Scene::volume_lights, core/scene/volume_emitter.h; docs/design/media.md "Emitting media as
// lights"). A volume light's point takes three numbers, its direction two, so it has routines of
// its own beside Light::illuminate and Light::emit. Without emitting media every routine here
// draws what sample_direct_light and Light::emit draw, in the same order.

#include <cmath>

#include "core/integrators/bidirectional/vcm_mis.h"
#include "core/integrators/direct_light.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/scene/volume_emitter.h"

namespace render {

// The start y_0 of a light subpath at a volume light: a point with density p_V, an isotropic
// direction, and the densities MIS needs (selection probability included): direct_pdf_a =
// P p_V (next-event estimation's, volume measure), emission_pdf_w = P p_V / 4 pi. y_0 emits if
// the subpath is in the medium there by the medium rule, read along its own first direction
// (VolumeEmitter::source_leaving): where shapes disagree about the medium, a position alone
// does not say.
struct VolumeLightSample {
    bool valid = false;
    Vec3 p, direction;
    Rgb source;  // sigma_a L_e at y_0
    float direct_pdf_a = 0, emission_pdf_w = 0;
};

inline VolumeLightSample sample_volume_light_start(const VolumeEmitter& emitter,
                                                   float pick_probability, Rng& rng) {
    const Vec3 u = rng.next_3d();
    const Vec2 ud = rng.next_2d();
    const VolumePointSample y = emitter.sample_point(u);
    VolumeLightSample out;
    out.p = y.p;
    out.direction = warp::square_to_uniform_sphere(ud);
    out.source = emitter.source_leaving(y.p, out.direction);
    out.direct_pdf_a = pick_probability * y.pdf_volume;
    out.emission_pdf_w = out.direct_pdf_a * kInv4Pi;
    out.valid = !y.source.is_black() && out.emission_pdf_w > 0;
    return out;
}

// MIS of a volume light (vcm_mis.h; docs/design/media.md): the light subpath's start is eqs.
// (31)-(33) with cos = 1 and the volume density in place of the area density, and the eye's
// collision estimate at a point y of the medium is eq. (43) with next-event estimation's density
// direct_pdf_a = P p_V(y) and the light subpath's P p_V(y) / 4 pi. The integrator and
// volume_emitter_mis_test call these same functions.
inline MisQuantities start_volume_light_mis(const VcmMis& mis, float direct_pdf_a) {
    return mis.start_light(direct_pdf_a, direct_pdf_a * kInv4Pi, 1.0f, false);
}
inline float volume_emission_weight(const VcmMis& mis, const MisQuantities& eye,
                                    float direct_pdf_a) {
    return mis.weight_emission(eye, direct_pdf_a, direct_pdf_a * kInv4Pi);
}
// Next-event estimation's light sample for the point y (density p_V) of a volume light, seen
// from `receiver`: "radiance" sigma_a L_e(y) (`source`), solid-angle density p_V |y - receiver|^2
// (a medium point has no cosine), emission density p_V / 4 pi. False when they coincide.
inline bool volume_light_illuminate(const Vec3& receiver, const Vec3& y, const Rgb& source,
                                    float pdf_volume, LightIlluminateSample& ls) {
    const Vec3 d = y - receiver;
    const float dist2 = length_squared(d);
    if (!(dist2 > 0)) return false;
    const float dist = std::sqrt(dist2);
    ls.wi = d / dist;
    ls.distance = dist;
    ls.radiance = source;
    ls.pdf_direct_w = pdf_volume * dist2;
    ls.pdf_emission_w = pdf_volume * kInv4Pi;
    ls.cos_at_light = 1.0f;
    return std::isfinite(ls.pdf_direct_w) && ls.pdf_direct_w > 0;
}

// Next-event estimation toward any emitter: as sample_direct_light, and for a volume light a
// point y with density p_V (volume_light_illuminate), so that radiance f / (P pdf_direct_w) T is
// the estimate of integral sigma_a L_e T f / d^2 dV. y emits if the shadow ray, leaving the
// receiver in medium_toward(wi), arrives there in the emitting medium (the medium rule along the
// path, not y's position: VolumeEmitter::source_seen_from).
template <class MediumToward>
inline bool sample_direct_emitter(const Scene& scene, const Vec3& receiver,
                                  const MediumToward& medium_toward, Rng& rng,
                                  DirectLightSample& out) {
    if (scene.volume_lights().empty()) return sample_direct_light(scene, receiver, rng, out);
    out.light = scene.sample_emitter(rng.next_1d(), &out.pick_probability);
    if (!out.light || !(out.pick_probability > 0)) return false;
    const VolumeEmitter* emitter = out.light->as_volume();
    if (!emitter) {
        const Vec2 u = rng.next_2d();
        return out.light->illuminate(receiver, u, out.ls) && out.ls.pdf_direct_w > 0;
    }
    const Vec3 u = rng.next_3d();
    const VolumePointSample y = emitter->sample_point(u);
    if (y.source.is_black() || !(y.pdf_volume > 0)) return false;
    if (!volume_light_illuminate(receiver, y.p, y.source, y.pdf_volume, out.ls)) return false;
    out.ls.radiance =
        emitter->source_seen_from(y.p, -out.ls.wi, out.ls.distance, medium_toward(out.ls.wi));
    return !out.ls.radiance.is_black();
}

}  // namespace render
