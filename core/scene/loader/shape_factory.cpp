#include "core/scene/loader/shape_factory.h"

#include "core/base/memory_budget.h"
#include "core/base/plugin_table.h"

#include <cmath>
#include <system_error>

#include "core/mesh_io/obj_reader.h"
#include "core/mesh_io/ply_reader.h"
#include "core/mesh_io/serialized_reader.h"
#include "core/shapes/curve.h"
#include "core/shapes/curve_input.h"
#include "core/shapes/disk.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

std::string shape_name(const Properties& props) {
    return props.id.empty() ? props.type() + " (" + props.where().to_string() + ")" : props.id;
}

// `file_face_normals`: the mesh file asks for flat shading (a serialized file's flag).
std::unique_ptr<Shape> make_mesh_shape(const Properties& props, MeshData data,
                                       bool allow_face_normals, bool file_face_normals = false) {
    Transform to_world = props.get_ray_transform("to_world");
    bool flip = props.get_bool("flip_normals", false);
    bool face_normals =
        (allow_face_normals && props.get_bool("face_normals", false)) || file_face_normals;
    if (data.indices.empty()) throw props.error("filename", "the mesh has no faces");
    if (data.normals.empty() && !face_normals) compute_vertex_normals(data, to_world);
    return std::make_unique<TriangleMesh>(std::move(data), to_world, flip, face_normals,
                                          shape_name(props));
}

// The file a shape's `filename` names (relative to the scene's folder); the error names the
// parameter when it is empty or not a regular file. `kind` says what the file holds.
std::filesystem::path shape_input_file(const Properties& props,
                                       const std::filesystem::path& scene_dir, const char* kind) {
    std::filesystem::path file = props.get_string("filename");
    if (file.empty()) throw props.error("filename", "empty file name");
    std::filesystem::path path = file.is_absolute() ? file : scene_dir / file;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw props.error("filename", std::string(kind) + " file not found: " + path.string());
    return path;
}

std::unique_ptr<Shape> make_file_mesh(const Properties& props,
                                      const std::filesystem::path& scene_dir) {
    const std::filesystem::path path = shape_input_file(props, scene_dir, "mesh");
    MeshData data;
    try {
        data = props.type() == "ply" ? read_ply(path) : read_obj(path);
    } catch (const SceneError& e) {
        rethrow_scene_error(e, props.error("filename", e.what()));
    }
    // Mitsuba's default: files store v upwards, textures are looked up with v = 0 at the top.
    if (props.get_bool("flip_tex_coords", true))
        for (Vec2& uv : data.uvs) uv.y = 1.0f - uv.y;
    return make_mesh_shape(props, std::move(data), true);
}

// Mitsuba's `serialized`: mesh `shape_index` of a compressed file. Its uv are used as stored
// (Mitsuba 3 takes no flip_tex_coords here); the file's face-normal flag acts as face_normals.
std::unique_ptr<Shape> make_serialized_mesh(const Properties& props) {
    const std::filesystem::path path = props.get_string("filename");
    if (path.empty()) throw props.error("filename", "empty file name");
    const int64_t index = props.get_int("shape_index", 0);
    if (index < 0) throw props.error("shape_index", "must be 0 or more");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw props.error("filename", "mesh file not found: " + path.string());
    SerializedMesh mesh;
    try {
        mesh = read_serialized(path, size_t(index));
    } catch (const SceneError& e) {
        rethrow_scene_error(e, props.error("filename", e.what()));
    }
    return make_mesh_shape(props, std::move(mesh.data), true, mesh.face_normals);
}

// Mitsuba 3's `bsplinecurve` and `linearcurve`: round curves from a file of control points
// and radii (core/shapes/curve_input.h); points go through to_world, radii are taken as written,
// as Mitsuba does.
std::unique_ptr<Shape> make_curve_file(const Properties& props,
                                       const std::filesystem::path& scene_dir) {
    const std::filesystem::path path = shape_input_file(props, scene_dir, "curve");
    const Transform to_world = props.get_ray_transform("to_world");
    try {
        std::vector<CurvePoints> curves = read_curve_file(path);
        for (CurvePoints& c : curves)
            for (Vec3& p : c.points) p = to_world.apply_point(p);
        return std::make_unique<Curves>(
            mitsuba_curve_segments(curves, props.type() == "bsplinecurve", shape_name(props)),
            CurveType::Cylinder, shape_name(props));
    } catch (const SceneError& e) {
        rethrow_scene_error(e, props.error("filename", e.what()));
    }
}

std::unique_ptr<Shape> make_sphere(const Properties& props) {
    Vec3 center = props.get_vec3("center", Vec3(0.0f));
    float radius = props.get_float("radius", 1.0f);
    if (!(radius > 0)) throw props.error("radius", "the radius must be positive");
    Transform to_world = props.get_ray_transform("to_world");
    bool flip = props.get_bool("flip_normals", false);
    // to_world must be a similarity: rotation/reflection, uniform scale and translation.
    const Transform::Matrix& m = to_world.matrix();
    if (m[3][0] != 0 || m[3][1] != 0 || m[3][2] != 0 || m[3][3] != 1)
        throw props.error("to_world", "a sphere's to_world cannot be projective");
    double scale2[3], off = 0;
    for (int i = 0; i < 3; ++i) {
        scale2[i] = 0;
        for (int r = 0; r < 3; ++r) scale2[i] += m[size_t(r)][size_t(i)] * m[size_t(r)][size_t(i)];
    }
    for (int i = 0; i < 3; ++i)
        for (int j = i + 1; j < 3; ++j) {
            double d = 0;
            for (int r = 0; r < 3; ++r) d += m[size_t(r)][size_t(i)] * m[size_t(r)][size_t(j)];
            off = std::max(off, std::abs(d));
        }
    double s2 = (scale2[0] + scale2[1] + scale2[2]) / 3;
    const double tol = 1e-4 * s2;
    if (!(s2 > 0) || std::abs(scale2[0] - s2) > tol || std::abs(scale2[1] - s2) > tol ||
        std::abs(scale2[2] - s2) > tol || off > tol)
        throw props.error("to_world",
                          "a sphere's to_world must be a similarity (rotation, uniform scale, "
                          "translation); a non-uniform scale would make an ellipsoid");
    Vec3 world_center = to_world.apply_point(center);
    float world_radius = float(radius * std::sqrt(s2));
    if (!is_finite(world_center) || !std::isfinite(world_radius))
        throw props.error("to_world", "the sphere's centre or radius is not finite");
    // The object's axes in world space, for the uv parametrisation (a reflection stays one).
    const Frame axes(normalize(to_world.apply_vector(Vec3(1, 0, 0))),
                     normalize(to_world.apply_vector(Vec3(0, 1, 0))),
                     normalize(to_world.apply_vector(Vec3(0, 0, 1))));
    return std::make_unique<Sphere>(world_center, world_radius, flip, shape_name(props), axes);
}

}  // namespace

void compute_vertex_normals(MeshData& mesh, const Transform& to_world) {
    std::vector<Vec3> world(mesh.positions.size());
    for (size_t i = 0; i < world.size(); ++i) world[i] = to_world.apply_point(mesh.positions[i]);
    bool mirrored = to_world.determinant3x3() < 0;  // TriangleMesh then reverses the winding
    std::vector<Vec3> normals(world.size(), Vec3(0.0f));
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
        uint32_t idx[3] = {mesh.indices[t], mesh.indices[t + 1], mesh.indices[t + 2]};
        if (idx[0] >= world.size() || idx[1] >= world.size() || idx[2] >= world.size())
            continue;  // TriangleMesh reports the bad index
        if (mirrored) std::swap(idx[1], idx[2]);
        Vec3 n = cross(world[idx[1]] - world[idx[0]], world[idx[2]] - world[idx[0]]);
        float len = length(n);
        if (!(len > 0) || !std::isfinite(len)) continue;
        n = n / len;
        for (int k = 0; k < 3; ++k) {
            Vec3 d0 = world[idx[(k + 1) % 3]] - world[idx[k]];
            Vec3 d1 = world[idx[(k + 2) % 3]] - world[idx[k]];
            float l0 = length(d0), l1 = length(d1);
            if (!(l0 > 0) || !(l1 > 0)) continue;
            float c = std::clamp(dot(d0, d1) / (l0 * l1), -1.0f, 1.0f);
            normals[idx[k]] += n * std::acos(c);
        }
    }
    // Object-space normals whose inverse transpose is the world normal: n_obj = M^T n_world.
    const Transform::Matrix& m = to_world.matrix();
    mesh.normals.resize(world.size());
    for (size_t i = 0; i < world.size(); ++i) {
        const Vec3& w = normals[i];
        Vec3 o;
        for (int c = 0; c < 3; ++c)
            o[c] = float(m[0][size_t(c)] * w.x + m[1][size_t(c)] * w.y + m[2][size_t(c)] * w.z);
        mesh.normals[i] = o;
    }
}

std::unique_ptr<Shape> make_shape(const Properties& props, const std::filesystem::path& scene_dir) {
    using Path = std::filesystem::path;
    static const Plugin<std::unique_ptr<Shape> (*)(const Properties&, const Path&)> kShapes[] = {
        {"rectangle", [](const Properties& p,
                         const Path&) { return make_mesh_shape(p, make_rectangle_mesh(), false); }},
        {"cube", [](const Properties& p,
                    const Path&) { return make_mesh_shape(p, make_cube_mesh(), false); }},
        {"sphere", [](const Properties& p, const Path&) { return make_sphere(p); }},
        {"disk",
         [](const Properties& p, const Path&) -> std::unique_ptr<Shape> {
             Transform to_world = p.get_ray_transform("to_world");
             bool flip = p.get_bool("flip_normals", false);
             return std::make_unique<Disk>(to_world, flip, shape_name(p));
         }},
        {"obj", make_file_mesh},
        {"ply", make_file_mesh},
        {"serialized", [](const Properties& p, const Path&) { return make_serialized_mesh(p); }},
        {"bsplinecurve", make_curve_file},
        {"linearcurve", make_curve_file},
    };
    return find_plugin(kShapes, props, "shape").create(props, scene_dir);
}

}  // namespace render
