#pragma once

// Upper bounds of the sizes of the records an iteration stores, for the per-iteration memory
// estimate (core/render/iteration_memory.cpp); subpath.h and iteration_storage.h check them with
// static_assert, so a record that grows past its bound fails the build instead of the estimate.

#include <cstddef>

namespace render::bidirectional {

inline constexpr size_t kLightVertexBytesBound = 128;  // a stored light vertex (LightVertex)
inline constexpr size_t kJoint2VertexBytesBound = 20;  // J2's state of one (Joint2Vertex)
inline constexpr size_t kPhotonBeamBytesBound = 128;   // a photon beam (PhotonBeam)
inline constexpr size_t kBeamReplayBytesBound = 24;    // its replay state, where it has one
inline constexpr size_t kLightRayBytesBound = 104;     // a J2 light ray (LightRay)

}  // namespace render::bidirectional
