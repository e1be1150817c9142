#pragma once

// Small scenes shared by several test files.

#include <string>

namespace render::testing {

// A small lit box (floor, cube, sphere, area light) with every shape and the camera uniformly
// scaled by the define $s (default 1): radiance does not depend on the scale, so neither may
// the image.
inline std::string scaled_box_scene() {
    return R"(<scene version="3.0.0">
  <default name="s" value="1"/>
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world">
      <lookat origin="0, 1, 4" target="0, 0.8, 0" up="0, 1, 0"/>
      <scale value="$s"/>
    </transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <bsdf type="twosided" id="white"><bsdf type="diffuse"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="2"/><scale value="$s"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="cube">
    <transform name="to_world"><scale value="0.4"/><translate y="0.4"/><scale value="$s"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="0.9" y="0.3" z="0.5"/>
    <float name="radius" value="0.3"/>
    <transform name="to_world"><scale value="$s"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="90"/><scale value="0.5"/><translate y="2"/><scale value="$s"/></transform>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter>
  </shape>
</scene>)";
}

// A medium furnace: a closed sphere of radius 1 (normals inward, `medium_xml`'s medium
// `medium_id` inside) whose diffuse wall of `wall_reflectance` emits `wall_radiance`, seen
// from its centre at 16 x 16 (volpt_test, volume_emission_test).
inline std::string medium_sphere_furnace(const std::string& medium_xml,
                                         const std::string& medium_id,
                                         const std::string& wall_reflectance,
                                         const std::string& wall_radiance) {
    return R"(<scene version="3.0.0">
  )" + medium_xml +
           R"(
  <sensor type="perspective">
    <float name="fov" value="70"/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0.3, 0.2, 1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
    <ref id=")" +
           medium_id +
           R"("/>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="1"/>
    <boolean name="flip_normals" value="true"/>
    <bsdf type="diffuse"><rgb name="reflectance" value=")" +
           wall_reflectance + R"("/></bsdf>
    <emitter type="area"><rgb name="radiance" value=")" +
           wall_radiance + R"("/></emitter>
    <ref name="exterior" id=")" +
           medium_id + R"("/>
  </shape>
</scene>)";
}

}  // namespace render::testing
