#include "core/media/vdb_file.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <mutex>
#include <sstream>

#include "core/base/error.h"
#include "core/base/memory_budget.h"

namespace render {
namespace {

void initialize_openvdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

SceneError error(const std::string& path, const std::string& message) {
    return SceneError(path + ": " + message);
}

}  // namespace

VolumeGridData read_vdb_file(const std::string& path) {
    initialize_openvdb();
    openvdb::FloatGrid::Ptr grid;
    try {
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
    } catch (const openvdb::Exception& e) {
        throw error(path, std::string("cannot read OpenVDB file: ") + e.what());
    } catch (const std::exception& e) {
        throw error(path, std::string("cannot read OpenVDB file: ") + e.what());
    }
    if (!grid) throw error(path, "the file has no float grid (a density grid is needed)");

    const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
    if (box.empty()) throw error(path, "grid \"" + grid->getName() + "\" has no active voxels");
    const openvdb::Coord dim = box.dim();
    VolumeGridData d;
    d.xres = dim.x();
    d.yres = dim.y();
    d.zres = dim.z();
    d.channels = 1;
    if (d.voxel_count() > kMaxVolumeValues || d.xres < 1 || d.yres < 1 || d.zres < 1) {
        std::ostringstream os;
        os << "grid \"" << grid->getName() << "\" is too large to densify (" << d.xres << " x "
           << d.yres << " x " << d.zres << " voxels)";
        throw error(path, os.str());
    }
    charge_scene_memory(4 * d.voxel_count(), path + ": grid \"" + grid->getName() + "\" densified");
    d.values.resize(d.voxel_count());
    openvdb::FloatGrid::ConstAccessor acc = grid->getConstAccessor();
    const openvdb::Coord lo = box.min();
    size_t i = 0;
    for (int z = 0; z < d.zres; ++z)
        for (int y = 0; y < d.yres; ++y)
            for (int x = 0; x < d.xres; ++x) d.values[i++] = acc.getValue(lo.offsetBy(x, y, z));

    // World box of the voxel boxes: the 8 corners of the index box, transformed.
    const openvdb::math::Transform& xf = grid->transform();
    for (int c = 0; c < 8; ++c) {
        openvdb::Vec3d idx((c & 1) ? box.max().x() + 0.5 : box.min().x() - 0.5,
                           (c & 2) ? box.max().y() + 0.5 : box.min().y() - 0.5,
                           (c & 4) ? box.max().z() + 0.5 : box.min().z() - 0.5);
        openvdb::Vec3d w = xf.indexToWorld(idx);
        d.bbox.expand(Vec3(float(w.x()), float(w.y()), float(w.z())));
    }
    return d;
}

void write_vdb_file(const std::string& path, const VolumeGridData& data) {
    if (data.channels != 1 || data.xres < 1 || data.yres < 1 || data.zres < 1 ||
        data.values.size() != data.voxel_count())
        throw error(path, "only consistent 1-channel grids can be written as .vdb");
    initialize_openvdb();
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    const Vec3 extent = data.bbox.hi - data.bbox.lo;
    const openvdb::Vec3d voxel(double(extent.x) / data.xres, double(extent.y) / data.yres,
                               double(extent.z) / data.zres);
    if (!(voxel.x() > 0 && voxel.y() > 0 && voxel.z() > 0))
        throw error(path, "the volume's bounding box must have a positive size");
    // index -> world: world = lo + (index + 1/2) * voxel.
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m.preScale(voxel);
    m.postTranslate(openvdb::Vec3d(data.bbox.lo.x + 0.5 * voxel.x(),
                                   data.bbox.lo.y + 0.5 * voxel.y(),
                                   data.bbox.lo.z + 0.5 * voxel.z()));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    openvdb::FloatGrid::Accessor acc = grid->getAccessor();
    size_t i = 0;
    for (int z = 0; z < data.zres; ++z)
        for (int y = 0; y < data.yres; ++y)
            for (int x = 0; x < data.xres; ++x)
                acc.setValueOn(openvdb::Coord(x, y, z), data.values[i++]);
    try {
        openvdb::io::File file(path);
        file.write({grid});
        file.close();
    } catch (const openvdb::Exception& e) {
        throw error(path, std::string("cannot write OpenVDB file: ") + e.what());
    }
}

}  // namespace render
