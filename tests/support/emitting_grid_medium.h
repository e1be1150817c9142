#pragma once

// The emitting medium of the emission closed forms (volume_emission_test, volume_emitter_test):
// sigma_t = (0.5, 1, 4), radiance L_e = (1, 2, 0.5) and an albedo, homogeneous or as a
// heterogeneous medium of constant grids. The grids cover [-1.25, 1.25]^3 (4^3 voxels; trilinear
// interpolation of a constant grid is that constant everywhere inside), so a constant grid
// must render what the homogeneous medium renders: the closed forms hold for both.

#include <unistd.h>

#include <filesystem>
#include <string>

#include "core/media/vol_file.h"

namespace render::testing {

// A folder (under the temporary directory, named after `tag` and the process) with the
// constant grids sigma_t.vol (RGB: spectral tracking), sigma_t_grey.vol (one channel, 1.5:
// classic delta tracking), radiance.vol and albedo.vol (0.6), written on first use.
inline std::filesystem::path constant_emission_grids(const std::string& tag) {
    const std::filesystem::path d =
        std::filesystem::temp_directory_path() / (tag + "_" + std::to_string(::getpid()));
    if (std::filesystem::exists(d / "albedo.vol")) return d;
    std::filesystem::create_directories(d);
    auto grid = [](int channels) {
        VolumeGridData g;
        g.xres = g.yres = g.zres = 4;
        g.channels = channels;
        g.bbox.lo = Vec3(-1.25f);
        g.bbox.hi = Vec3(1.25f);
        return g;
    };
    auto write = [&](const std::string& name, const Rgb& value) {
        VolumeGridData g = grid(3);
        g.values.resize(g.voxel_count() * 3);
        for (size_t i = 0; i < g.voxel_count(); ++i)
            for (int c = 0; c < 3; ++c) g.values[3 * i + size_t(c)] = value[c];
        write_vol_file((d / name).string(), g);
    };
    write("sigma_t.vol", Rgb(0.5f, 1.0f, 4.0f));
    write("radiance.vol", Rgb(1.0f, 2.0f, 0.5f));
    VolumeGridData grey = grid(1);
    grey.values.assign(grey.voxel_count(), 1.5f);
    write_vol_file((d / "sigma_t_grey.vol").string(), grey);
    write("albedo.vol", Rgb(0.6f));  // last: its presence means the folder is complete
    return d;
}

// The medium "glow": homogeneous, or heterogeneous with the grids above (albedo "0" as a
// constant, any other value as albedo.vol, whose value is 0.6).
inline std::string emitting_medium_xml(bool grid, const std::string& albedo,
                                       const std::string& sigma_t_file = "sigma_t.vol") {
    if (!grid)
        return R"(<medium type="homogeneous" id="glow">
    <rgb name="sigma_t" value="0.5, 1, 4"/>
    <float name="albedo" value=")" +
               albedo + R"("/>
    <rgb name="radiance" value="1, 2, 0.5"/>
  </medium>)";
    const std::string albedo_xml =
        albedo == "0"
            ? R"(<float name="albedo" value="0"/>)"
            : R"(<volume type="gridvolume" name="albedo"><string name="filename" value="albedo.vol"/><boolean name="use_grid_bbox" value="true"/></volume>)";
    return R"(<medium type="heterogeneous" id="glow">
    <volume type="gridvolume" name="sigma_t"><string name="filename" value=")" +
           sigma_t_file + R"("/><boolean name="use_grid_bbox" value="true"/></volume>
    <volume type="gridvolume" name="radiance"><string name="filename" value="radiance.vol"/><boolean name="use_grid_bbox" value="true"/></volume>
    )" + albedo_xml +
           R"(
  </medium>)";
}

}  // namespace render::testing
