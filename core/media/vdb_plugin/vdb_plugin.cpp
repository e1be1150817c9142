// librender_volume_vdb.so: .vdb grids through OpenVDB, loaded by core on demand
// (core/media/vdb_plugin.h). Not part of render_core; only this file includes OpenVDB.

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <limits>
#include <mutex>
#include <optional>
#include <string>

#include "core/media/vdb_plugin.h"

namespace {

void set_error(char* error, size_t error_size, const std::string& message) {
    if (!error || error_size == 0) return;
    std::snprintf(error, error_size, "%s", message.empty() ? "unknown error" : message.c_str());
}

void initialize_openvdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

// The body returns 0, 2 (the sink refused) or an error message; exceptions become messages
// prefixed with `what_failed`.
template <class Body>
int guarded(char* error, size_t error_size, const char* what_failed, Body&& body) {
    try {
        const std::optional<std::string> message = body();
        if (!message) return 0;
        if (message->empty()) return 2;
        set_error(error, error_size, *message);
    } catch (const std::exception& e) {
        set_error(error, error_size, std::string(what_failed) + e.what());
    } catch (...) {
        set_error(error, error_size, std::string(what_failed) + "unknown exception");
    }
    return 1;
}

int read(const char* path, const RenderVolumeReadSink* sink, char* error, size_t error_size) {
    return guarded(
        error, error_size, "cannot read OpenVDB file: ", [&]() -> std::optional<std::string> {
            initialize_openvdb();
            openvdb::FloatGrid::Ptr grid;
            openvdb::io::File file(path);
            file.open();
            openvdb::GridPtrVecPtr grids = file.getGrids();
            for (const openvdb::GridBase::Ptr& g : *grids) {
                auto float_grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
                if (!float_grid) continue;
                if (!grid || g->getName() == "density") grid = float_grid;
                if (g->getName() == "density") break;
            }
            file.close();
            if (!grid) return std::string("the file has no float grid (a density grid is needed)");

            const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
            if (box.empty()) return "grid \"" + grid->getName() + "\" has no active voxels";
            const openvdb::Coord dim = box.dim();

            // World box of the voxel boxes: the 8 corners of the index box, transformed.
            float bounds[6] = {
                std::numeric_limits<float>::infinity(),  std::numeric_limits<float>::infinity(),
                std::numeric_limits<float>::infinity(),  -std::numeric_limits<float>::infinity(),
                -std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()};
            const openvdb::math::Transform& xf = grid->transform();
            for (int c = 0; c < 8; ++c) {
                openvdb::Vec3d idx((c & 1) ? box.max().x() + 0.5 : box.min().x() - 0.5,
                                   (c & 2) ? box.max().y() + 0.5 : box.min().y() - 0.5,
                                   (c & 4) ? box.max().z() + 0.5 : box.min().z() - 0.5);
                openvdb::Vec3d w = xf.indexToWorld(idx);
                for (int a = 0; a < 3; ++a) {
                    bounds[a] = std::min(bounds[a], float(w[a]));
                    bounds[3 + a] = std::max(bounds[3 + a], float(w[a]));
                }
            }
            float* values = sink->begin(sink->context, grid->getName().c_str(), dim.x(), dim.y(),
                                        dim.z(), bounds);
            if (!values) return std::string();  // refused: the caller knows why
            openvdb::FloatGrid::ConstAccessor acc = grid->getConstAccessor();
            const openvdb::Coord lo = box.min();
            size_t i = 0;
            for (int z = 0; z < dim.z(); ++z)
                for (int y = 0; y < dim.y(); ++y)
                    for (int x = 0; x < dim.x(); ++x)
                        values[i++] = acc.getValue(lo.offsetBy(x, y, z));
            return std::nullopt;
        });
}

int write(const char* path, int xres, int yres, int zres, const float bounds[6],
          const float* values, char* error, size_t error_size) {
    return guarded(
        error, error_size, "cannot write OpenVDB file: ", [&]() -> std::optional<std::string> {
            initialize_openvdb();
            openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
            grid->setName("density");
            grid->setGridClass(openvdb::GRID_FOG_VOLUME);
            const openvdb::Vec3d voxel(double(bounds[3] - bounds[0]) / xres,
                                       double(bounds[4] - bounds[1]) / yres,
                                       double(bounds[5] - bounds[2]) / zres);
            if (!(voxel.x() > 0 && voxel.y() > 0 && voxel.z() > 0))
                return std::string("the volume's bounding box must have a positive size");
            // index -> world: world = lo + (index + 1/2) * voxel.
            openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
            m.preScale(voxel);
            m.postTranslate(openvdb::Vec3d(bounds[0] + 0.5 * voxel.x(), bounds[1] + 0.5 * voxel.y(),
                                           bounds[2] + 0.5 * voxel.z()));
            grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
            openvdb::FloatGrid::Accessor acc = grid->getAccessor();
            size_t i = 0;
            for (int z = 0; z < zres; ++z)
                for (int y = 0; y < yres; ++y)
                    for (int x = 0; x < xres; ++x)
                        acc.setValueOn(openvdb::Coord(x, y, z), values[i++]);
            openvdb::io::File file(path);
            file.write({grid});
            file.close();
            return std::nullopt;
        });
}

const RenderVolumePlugin kPlugin = {RENDER_VOLUME_PLUGIN_VERSION, &read, &write};

}  // namespace

extern "C" __attribute__((visibility("default"))) const RenderVolumePlugin* render_volume_plugin_v1(
    void) {
    return &kPlugin;
}
