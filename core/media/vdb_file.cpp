#include "core/media/vdb_file.h"

#include <exception>
#include <sstream>
#include <stdexcept>

#include "core/base/dynamic_plugin.h"
#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/media/vdb_plugin.h"

namespace render {
namespace {

SceneError error(const std::string& path, const std::string& message) {
    return SceneError(path + ": " + message);
}

const RenderVolumePlugin& plugin_for(const std::string& path, const std::string& purpose) {
    try {
        return volume_plugin(purpose + " " + path);
    } catch (const std::runtime_error& e) {
        throw error(path, e.what());
    }
}

// The read sink: checks the grid's size and charges the memory budget before the plugin fills
// the array; an exception is kept here and rethrown on this side of the C interface.
struct ReadTarget {
    std::string path;
    VolumeGridData data;
    std::exception_ptr refused;

    static float* begin(void* context, const char* grid_name, int xres, int yres, int zres,
                        const float bounds[6]) {
        auto* self = static_cast<ReadTarget*>(context);
        try {
            VolumeGridData& d = self->data;
            d.xres = xres, d.yres = yres, d.zres = zres, d.channels = 1;
            if (d.voxel_count() > kMaxVolumeValues || d.xres < 1 || d.yres < 1 || d.zres < 1) {
                std::ostringstream os;
                os << "grid \"" << grid_name << "\" is too large to densify (" << d.xres << " x "
                   << d.yres << " x " << d.zres << " voxels)";
                throw error(self->path, os.str());
            }
            charge_scene_memory(4 * d.voxel_count(),
                                self->path + ": grid \"" + grid_name + "\" densified");
            d.values.resize(d.voxel_count());
            d.bbox.expand(Vec3(bounds[0], bounds[1], bounds[2]));
            d.bbox.expand(Vec3(bounds[3], bounds[4], bounds[5]));
            return d.values.data();
        } catch (...) {
            self->refused = std::current_exception();
            return nullptr;
        }
    }
};

}  // namespace

const RenderVolumePlugin& volume_plugin(const std::string& purpose) {
    struct Loaded {
        const RenderVolumePlugin* plugin = nullptr;
        std::string failures;
    };
    static const Loaded loaded = [] {
        Loaded l;
        const DynamicPluginSpec spec{RENDER_VOLUME_PLUGIN_FILE, "RENDER_VOLUME_PLUGIN",
                                     RENDER_VOLUME_PLUGIN_ENTRY};
        l.plugin = static_cast<const RenderVolumePlugin*>(load_dynamic_plugin(
            spec,
            [](void* entry, std::string* why) -> const void* {
                const RenderVolumePlugin* plugin =
                    entry ? reinterpret_cast<RenderVolumePluginEntry>(entry)() : nullptr;
                if (plugin && plugin->version == RENDER_VOLUME_PLUGIN_VERSION && plugin->read &&
                    plugin->write)
                    return plugin;
                *why = "not a version " + std::to_string(RENDER_VOLUME_PLUGIN_VERSION) +
                       " volume plugin (" RENDER_VOLUME_PLUGIN_ENTRY ")";
                return nullptr;
            },
            &l.failures));
        return l;
    }();
    if (!loaded.plugin)
        throw std::runtime_error(
            std::string("the volume plugin " RENDER_VOLUME_PLUGIN_FILE " (OpenVDB), needed ") +
            purpose +
            ", cannot be loaded (set RENDER_VOLUME_PLUGIN to its path); tried:" + loaded.failures);
    return *loaded.plugin;
}

VolumeGridData read_vdb_file(const std::string& path) {
    const RenderVolumePlugin& plugin = plugin_for(path, "to read");
    ReadTarget target{path, {}, nullptr};
    const RenderVolumeReadSink sink{&target, &ReadTarget::begin};
    char message[1024] = "";
    const int status = plugin.read(path.c_str(), &sink, message, sizeof message);
    if (status == 2 && target.refused) std::rethrow_exception(target.refused);
    if (status != 0) throw error(path, message);
    return std::move(target.data);
}

void write_vdb_file(const std::string& path, const VolumeGridData& data) {
    if (data.channels != 1 || data.xres < 1 || data.yres < 1 || data.zres < 1 ||
        data.values.size() != data.voxel_count())
        throw error(path, "only consistent 1-channel grids can be written as .vdb");
    const RenderVolumePlugin& plugin = plugin_for(path, "to write");
    const float bounds[6] = {data.bbox.lo.x, data.bbox.lo.y, data.bbox.lo.z,
                             data.bbox.hi.x, data.bbox.hi.y, data.bbox.hi.z};
    char message[1024] = "";
    if (plugin.write(path.c_str(), data.xres, data.yres, data.zres, bounds, data.values.data(),
                     message, sizeof message) != 0)
        throw error(path, message);
}

}  // namespace render
