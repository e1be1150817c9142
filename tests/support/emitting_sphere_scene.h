#pragma once

// The scene of the emission closed forms (volume_emission_test, volume_emitter_test): a unit
// sphere of the medium with id "glow" given as XML (null boundary) seen from (0, y, -5) along
// +z with a field of view of 0.02 degrees. Every camera ray crosses the sphere within 1e-3 of
// the line x = 0, y = y, whose chord is 2 sqrt(1 - y^2); over the pixels the chord varies by a
// relative 1e-6 at most (the linear part cancels by symmetry), so every pixel sees the closed
// form of that chord.

#include <string>

namespace render::testing {

inline std::string emitting_sphere_seen_from_outside(const std::string& medium_xml, double y) {
    const std::string ys = std::to_string(y);
    return R"(<scene version="3.0.0">
  )" + medium_xml +
           R"(
  <sensor type="perspective">
    <float name="fov" value="0.02"/>
    <transform name="to_world"><lookat origin="0, )" +
           ys + R"(, -5" target="0, )" + ys + R"(, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="1"/>
    <bsdf type="null"/>
    <ref name="interior" id="glow"/>
  </shape>
</scene>)";
}

}  // namespace render::testing
