#include "core/media/volume_factory.h"

#include "core/base/memory_budget.h"
#include "core/base/plugin_table.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>

#include "core/media/constant_volume.h"
#include "core/media/grid_volume.h"
#include "core/media/vdb_file.h"
#include "core/media/vol_file.h"

namespace render {
namespace {

std::string lower_extension(const std::filesystem::path& p) {
    std::string e = p.extension().string();
    std::transform(e.begin(), e.end(), e.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return e;
}

std::shared_ptr<const Volume> make_grid_volume(const Properties& props,
                                               const std::string& scene_dir) {
    const std::string filename = props.get_string("filename");
    std::filesystem::path path(filename);
    if (path.is_relative() && !scene_dir.empty()) path = std::filesystem::path(scene_dir) / path;

    VolumeFilter filter = VolumeFilter::kTrilinear;
    const std::string filter_type = props.get_string("filter_type", "trilinear");
    if (filter_type == "nearest")
        filter = VolumeFilter::kNearest;
    else if (filter_type != "trilinear")
        throw props.error("filter_type", "unknown filter type \"" + filter_type +
                                             "\" (supported: trilinear, nearest)");
    const std::string wrap_mode = props.get_string("wrap_mode", "clamp");
    if (wrap_mode != "clamp")
        throw props.error("wrap_mode",
                          "wrap mode \"" + wrap_mode + "\" is not supported yet (only clamp)");
    Transform to_world = props.get_ray_transform("to_world");
    const bool use_grid_bbox = props.get_bool("use_grid_bbox", false);

    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw props.error("filename", "volume file not found: " + path.string());
    VolumeGridData data;
    try {
        const std::string ext = lower_extension(path);
        if (ext == ".vol")
            data = read_vol_file(path.string());
        else if (ext == ".vdb")
            data = read_vdb_file(path.string());
        else
            throw SceneError(path.string() + ": unknown volume file type \"" + ext +
                             "\" (supported: .vol, .vdb)");
        check_volume_values(data, path.string());
    } catch (const SceneError& e) {
        rethrow_scene_error(e, props.error("filename", e.what()));
    }
    if (use_grid_bbox) {
        const Vec3 extent = data.bbox.hi - data.bbox.lo;
        if (!(is_finite(data.bbox.lo) && is_finite(extent) && extent.x > 0 && extent.y > 0 &&
              extent.z > 0))
            throw props.error("use_grid_bbox",
                              path.string() + ": the file's bounding box is empty or not finite");
        to_world = to_world * Transform::translate(data.bbox.lo) * Transform::scale(extent);
    }
    return std::make_shared<GridVolume>(std::move(data), to_world, filter, path.string());
}

}  // namespace

std::shared_ptr<const Volume> make_volume(const Properties& props, const std::string& scene_dir) {
    static const Plugin<std::shared_ptr<const Volume> (*)(const Properties&, const std::string&)>
        kVolumes[] = {
            {"constvolume",
             [](const Properties& p, const std::string&) -> std::shared_ptr<const Volume> {
                 const Rgb value = p.get_rgb("value", Rgb(1.0f));
                 if (!value.is_finite() || value.r < 0 || value.g < 0 || value.b < 0)
                     throw p.error("value", "must be finite and >= 0");
                 // Mitsuba accepts a placement; a constant reads the same everywhere after any.
                 if (p.has("to_world")) (void)p.get_transform("to_world");
                 return std::make_shared<ConstantVolume>(value);
             }},
            {"gridvolume", make_grid_volume},
        };
    return find_plugin(kVolumes, props, "volume").create(props, scene_dir);
}

}  // namespace render
