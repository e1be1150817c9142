#pragma once

// The scene the server's unit tests submit: an 8x6 film inside a sphere whose inside is
// diffuse and emitting (every pixel sees it), its reflectance the define $r (default 0.5), so
// that an animation's frames can change it, or break it (r=oops).

namespace render::testing {

inline constexpr const char* kServerTestScene = R"(<scene version="3.0.0">
  <default name="r" value="0.5"/>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="2"/>
    <boolean name="flip_normals" value="true"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="$r"/></bsdf>
    <emitter type="area"><rgb name="radiance" value="0.5"/></emitter>
  </shape>
</scene>)";

}  // namespace render::testing
