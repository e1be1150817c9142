#pragma once

#include "core/integrators/bidirectional/iteration.h"

namespace render {

// The eye pass of many-light rendering: the eye follows delta lobes from the camera and, at its
// first non-delta vertex, adds next-event estimation and its VPL connections (every VPL for vpl,
// a few drawn from the importance caches for ic), all with weight 1; emission is counted where
// the eye sees it directly or through delta lobes only.
Rgb trace_many_light_eye_path(const bidirectional::Iteration& iteration, uint64_t pixel,
                              RenderStats& stats, const LayerSink& sink);

}  // namespace render
