#pragma once

// pbrt-v4's graphics state: what AttributeBegin saves and AttributeEnd restores.

#include <memory>
#include <optional>
#include <string>

#include "core/materials/bsdf.h"
#include "core/math/transform.h"
#include "core/media/medium.h"
#include "core/scene/pbrt/parameters.h"

namespace render::pbrt {

struct AreaLightState {
    std::string type;
    std::shared_ptr<const ParamList> params;
};

struct GraphicsState {
    Transform ctm;  // object-to-world (world-to-camera before WorldBegin)
    bool reverse_orientation = false;
    std::shared_ptr<const Bsdf> material;  // null: pbrt's default, diffuse 0.5
    std::optional<AreaLightState> area_light;
    // MediumInterface: the media inside and outside the following shapes (null: vacuum); the
    // outside one also holds the camera and lights defined next.
    const Medium* inside = nullptr;
    const Medium* outside = nullptr;
};

}  // namespace render::pbrt
