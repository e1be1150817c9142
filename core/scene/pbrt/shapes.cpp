// pbrt-v4 shapes: trianglemesh, plymesh and planar bilinearmesh as our TriangleMesh, non-planar
// bilinearmesh and a plymesh's non-planar quads as BilinearPatches; sphere and disk
// through the Mitsuba loader's shape factory; curve as Curves (core/shapes/curve.h).
// docs/reference/scene-format.md, "pbrt-v4 scenes".

#include <cmath>

#include "core/base/memory_budget.h"
#include "core/base/properties.h"
#include "core/mesh_io/mesh_limits.h"
#include "core/mesh_io/ply_reader.h"
#include "core/scene/loader/shape_factory.h"
#include "core/scene/pbrt/builders.h"
#include "core/shapes/bilinear_patch.h"
#include "core/shapes/curve.h"
#include "core/shapes/curve_input.h"
#include "core/shapes/triangle_mesh.h"

namespace render::pbrt {
namespace {

std::vector<Vec3> vec3s(const std::vector<double>& v) {
    std::vector<Vec3> out(v.size() / 3);
    for (size_t i = 0; i < out.size(); ++i)
        out[i] = Vec3(float(v[3 * i]), float(v[3 * i + 1]), float(v[3 * i + 2]));
    return out;
}

// pbrt orients a triangle whose mesh has normals towards them (its geometric normal is flipped
// to the shading normal's side); ours follow the winding. Reverses triangles whose winding
// disagrees with their vertex normals (object space: TriangleMesh keeps the two consistent
// under the transform).
void orient_to_normals(MeshData& mesh) {
    if (mesh.normals.size() != mesh.positions.size()) return;
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
        const uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
        if (a >= mesh.positions.size() || b >= mesh.positions.size() || c >= mesh.positions.size())
            continue;  // TriangleMesh reports the bad index
        const Vec3 ng =
            cross(mesh.positions[b] - mesh.positions[a], mesh.positions[c] - mesh.positions[a]);
        const Vec3 ns = mesh.normals[a] + mesh.normals[b] + mesh.normals[c];
        if (dot(ng, ns) < 0) std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
    }
}

// uv as pbrt writes them (v up) to our lookups' convention (v = 0 at the image's top), as the
// Mitsuba loader flips mesh files' v.
void flip_v(MeshData& mesh) {
    for (Vec2& uv : mesh.uvs) uv.y = 1.0f - uv.y;
}

std::unique_ptr<Shape> finish_mesh(MeshData mesh, const ParamList& params,
                                   const Transform& to_world, bool reverse_orientation) {
    if (mesh.indices.empty()) throw params.error("indices", "the mesh has no triangles");
    orient_to_normals(mesh);
    flip_v(mesh);
    // Without normals pbrt shades with the geometric normal (flat).
    const bool flat = mesh.normals.empty();
    try {
        return std::make_unique<TriangleMesh>(
            std::move(mesh), to_world, reverse_orientation, flat,
            params.context() + " (" + params.where.to_string() + ")");
    } catch (const SceneError& e) {
        rethrow_scene_error(e, SceneError(params.where, e.what()));
    }
}

// The mesh limits and the memory budget, as for PLY and OBJ files (the parameter lists
// themselves are bounded by the file's size, charged when it was read).
void check_inline_mesh(const ParamList& params, uint64_t vertices, uint64_t triangles) {
    try {
        check_mesh_counts("the mesh", vertices, triangles);
        charge_scene_memory(
            mesh_vertex_bytes(vertices, true, true) + mesh_triangle_bytes(triangles), "the mesh");
    } catch (const SceneError& e) {
        rethrow_scene_error(e, params.error("P", e.what()));
    }
}

// Whether the bilinear patch p00 p10 p01 p11 is flat (its fourth corner within 1e-4 of its size
// of the plane of the other three): then its two triangles (p00 p10 p11, p00 p11 p01) are it.
bool patch_is_planar(const Vec3& p00, const Vec3& p10, const Vec3& p01, const Vec3& p11) {
    const Vec3 n = cross(p10 - p00, p01 - p00);
    const float size = std::max(length(p10 - p00), length(p01 - p00));
    const float len = length(n);
    return !(len > 0 && std::abs(dot(n / len, p11 - p00)) > 1e-4f * size);
}

// A trianglemesh (corners 3) or bilinearmesh (corners 4). Non-planar bilinear patches are left
// in `patches` (4 indices each) with mesh.indices empty.
MeshData inline_mesh(const ParamList& params, size_t corners, std::vector<uint32_t>* patches) {
    MeshData mesh;
    mesh.positions = vec3s(params.get_numbers("P", {"point3", "point"}, 3));
    if (mesh.positions.empty()) throw params.error("P", "the vertex positions are required");
    std::vector<long long> indices = params.get_ints("indices");
    if (indices.empty()) {
        if (mesh.positions.size() != corners)
            throw params.error("indices", "required unless the mesh is a single " +
                                              std::string(corners == 3 ? "triangle" : "patch"));
        for (size_t i = 0; i < corners; ++i) indices.push_back((long long)i);
    }
    if (indices.size() % corners != 0)
        throw params.error("indices", "the count, " + std::to_string(indices.size()) +
                                          ", is not a multiple of " + std::to_string(corners));
    for (long long i : indices)
        if (i < 0 || size_t(i) >= mesh.positions.size())
            throw params.error("indices", "index " + std::to_string(i) + " is out of range (" +
                                              std::to_string(mesh.positions.size()) + " vertices)");
    check_inline_mesh(params, mesh.positions.size(), indices.size() / corners * (corners - 2));
    mesh.normals = vec3s(params.get_numbers("N", {"normal", "normal3"}, 3));
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
        throw params.error("N", "one normal per vertex is needed");
    const std::vector<double> uv = params.get_numbers("uv", {"point2", "float"}, 2);
    for (size_t i = 0; i + 1 < uv.size(); i += 2)
        mesh.uvs.emplace_back(float(uv[i]), float(uv[i + 1]));
    if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
        throw params.error("uv", "one uv per vertex is needed");
    if (corners == 3) {
        for (long long i : indices) mesh.indices.push_back(uint32_t(i));
        params.get_ints("faceIndices");  // per-face ids for Ptex: no effect here
        return mesh;
    }
    // Bilinear patches (p00, p10, p01, p11): when every one is planar, two triangles each,
    // which reproduce them exactly; otherwise the patches themselves (`patches`).
    bool planar = true;
    for (size_t q = 0; q < indices.size() && planar; q += 4)
        planar = patch_is_planar(
            mesh.positions[size_t(indices[q])], mesh.positions[size_t(indices[q + 1])],
            mesh.positions[size_t(indices[q + 2])], mesh.positions[size_t(indices[q + 3])]);
    if (!planar) {
        for (long long i : indices) patches->push_back(uint32_t(i));
        return mesh;
    }
    for (size_t q = 0; q < indices.size(); q += 4) {
        const uint32_t v[4] = {uint32_t(indices[q]), uint32_t(indices[q + 1]),
                               uint32_t(indices[q + 2]), uint32_t(indices[q + 3])};
        for (uint32_t i : {v[0], v[1], v[3], v[0], v[3], v[2]}) mesh.indices.push_back(i);
    }
    return mesh;
}

// Non-planar bilinear patches (core/shapes/bilinear_patch.h), in world space. The normal
// flips with ReverseOrientation and with a mirroring transform, as pbrt-v4's (and our triangles:
// the vertex normals, transformed as normals, only with ReverseOrientation).
std::unique_ptr<Shape> patch_shape(MeshData mesh, std::vector<uint32_t> patches,
                                   const ParamList& params, const Transform& to_world,
                                   bool reverse_orientation) {
    if (to_world.is_singular()) throw params.error("P", "the transform is singular");
    for (Vec3& p : mesh.positions) p = to_world.apply_point(p);
    for (Vec3& n : mesh.normals) {
        const Vec3 w = to_world.apply_normal(n);
        const float len = length(w);
        n = len > 0 && std::isfinite(len) ? w / len : Vec3(0.0f);
        if (reverse_orientation) n = -n;  // as TriangleMesh's flip_normals
    }
    flip_v(mesh);
    const bool flip = reverse_orientation != (to_world.determinant3x3() < 0);
    try {
        return std::make_unique<BilinearPatches>(
            std::move(mesh.positions), std::move(patches), std::move(mesh.normals),
            std::move(mesh.uvs), flip, params.context() + " (" + params.where.to_string() + ")");
    } catch (const SceneError& e) {
        rethrow_scene_error(e, SceneError(params.where, e.what()));
    }
}

// pbrt-v4 reads a PLY file's four-sided faces as bilinear patches, corners v0 v1 v3 v2 as
// p00 p10 p01 p11 (its TriQuadMesh). As for bilinearmesh: when all are planar the fan's two
// triangles per face, which read_ply already made, are them exactly and stay; otherwise every
// quad becomes a patch (returned) and its triangles leave `mesh`.
std::vector<uint32_t> ply_patches(MeshData& mesh, const std::vector<PlyQuad>& quads) {
    bool planar = true;
    for (size_t q = 0; q < quads.size() && planar; ++q) {
        const uint32_t* v = quads[q].v;
        planar = patch_is_planar(mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[3]],
                                 mesh.positions[v[2]]);
    }
    if (planar) return {};
    std::vector<uint32_t> patches;
    patches.reserve(4 * quads.size());
    std::vector<bool> from_quad(mesh.indices.size() / 3, false);
    for (const PlyQuad& q : quads) {
        patches.insert(patches.end(), {q.v[0], q.v[1], q.v[3], q.v[2]});
        from_quad[q.first_triangle] = from_quad[q.first_triangle + 1] = true;
    }
    std::vector<uint32_t> triangles;
    for (size_t t = 0; t < from_quad.size(); ++t)
        if (!from_quad[t])
            triangles.insert(triangles.end(), mesh.indices.begin() + long(3 * t),
                             mesh.indices.begin() + long(3 * t + 3));
    mesh.indices = std::move(triangles);
    return patches;
}

// pbrt-v4's curve (docs/reference/scene-format.md, "Curves"): points to world space, widths
// scaled by the transform's mean scale (pbrt-v4 intersects in object space; the same for
// similarity transforms).
std::unique_ptr<Shape> curve_shape(const ParamList& params, const Transform& to_world) {
    std::vector<Vec3> points = vec3s(params.get_numbers("P", {"point3", "point"}, 3));
    if (points.empty()) throw params.error("P", "the control points are required");
    for (Vec3& p : points) p = to_world.apply_point(p);
    const std::string basis_name = params.get_string("basis", "bezier");
    if (basis_name != "bezier" && basis_name != "bspline")
        throw params.error("basis", "must be \"bezier\" or \"bspline\"");
    const std::string type_name = params.get_string("type", "flat");
    CurveType type;
    if (type_name == "flat")
        type = CurveType::Flat;
    else if (type_name == "cylinder")
        type = CurveType::Cylinder;
    else if (type_name == "ribbon")
        type = CurveType::Ribbon;
    else
        throw params.error("type", "must be \"flat\", \"cylinder\" or \"ribbon\"");
    std::vector<Vec3> normals = vec3s(params.get_numbers("N", {"normal", "normal3"}, 3));
    if (type == CurveType::Ribbon && normals.empty())
        throw params.error("N", "a ribbon curve needs normals \"N\" at its segment ends");
    if (type != CurveType::Ribbon && !normals.empty()) {
        warn(params.find("N")->where, params.context() + ": \"N\" is only used by ribbon curves");
        normals.clear();
    }
    for (Vec3& n : normals) n = normalize(to_world.apply_normal(n));
    const double width = params.get_float("width", 1.0);
    const double width0 = params.get_float("width0", width),
                 width1 = params.get_float("width1", width);
    for (const char* name : {"width", "width0", "width1"})
        if (params.has(name) && !(params.get_float(name, 0) >= 0))
            throw params.error(name, "must be non-negative");
    if (params.has("splitdepth")) {
        params.get_int("splitdepth", 3);
        warn(params.find("splitdepth")->where,
             params.context() + ": \"splitdepth\" is ignored (Embree intersects the curve itself)");
    }
    const float scale = float(std::cbrt(std::abs(to_world.determinant3x3())));
    const int degree = int(params.get_int("degree", 3));
    try {
        std::vector<CurveSegment> segments = pbrt_curve_segments(
            points, basis_name == "bezier" ? CurveBasis::Bezier : CurveBasis::BSpline, degree,
            float(width0) * scale, float(width1) * scale, normals, params.context());
        return std::make_unique<Curves>(std::move(segments), type,
                                        params.context() + " (" + params.where.to_string() + ")");
    } catch (const SceneError& e) {
        rethrow_scene_error(e, params.error("P", e.what()));
    }
    return nullptr;
}

void refuse_partial(const ParamList& params, const char* name, double full) {
    if (params.get_float(name, full) != full)
        throw params.error(name, "partial shapes are not supported yet");
}

}  // namespace

std::vector<std::unique_ptr<Shape>> make_shapes(
    const std::string& type, const ParamList& params, const Transform& to_world,
    bool reverse_orientation,
    const std::function<std::filesystem::path(const ParamList&, const std::string&)>& resolve) {
    std::unique_ptr<Shape> shape, second;
    if (type == "trianglemesh" || type == "bilinearmesh") {
        if (params.has("S")) throw params.error("S", "per-vertex tangents are not supported");
        std::vector<uint32_t> patches;
        MeshData mesh = inline_mesh(params, type == "trianglemesh" ? 3 : 4, &patches);
        shape = patches.empty()
                    ? finish_mesh(std::move(mesh), params, to_world, reverse_orientation)
                    : patch_shape(std::move(mesh), std::move(patches), params, to_world,
                                  reverse_orientation);
    } else if (type == "plymesh") {
        const std::string name = params.get_string("filename", "");
        if (name.empty()) throw params.error("filename", "a file name is required");
        const std::filesystem::path path = resolve(params, "filename");
        std::error_code ec;
        if (!std::filesystem::is_regular_file(path, ec))
            throw params.error("filename", "mesh file not found: " + path.string());
        MeshData mesh;
        std::vector<PlyQuad> quads;
        try {
            mesh = read_ply(path, &quads);
        } catch (const SceneError& e) {
            rethrow_scene_error(e, params.error("filename", e.what()));
        }
        if (params.has("displacement"))
            throw params.error("displacement", "displacement is not supported");
        std::vector<uint32_t> patches = ply_patches(mesh, quads);
        if (patches.empty()) {
            shape = finish_mesh(std::move(mesh), params, to_world, reverse_orientation);
        } else {
            MeshData corners;
            corners.positions = mesh.positions;
            corners.normals = mesh.normals;
            corners.uvs = mesh.uvs;
            shape = patch_shape(std::move(corners), std::move(patches), params, to_world,
                                reverse_orientation);
            if (!mesh.indices.empty())
                second = finish_mesh(std::move(mesh), params, to_world, reverse_orientation);
        }
    } else if (type == "sphere") {
        // pbrt flips a quadric's normal when the transform swaps handedness (a mirrored sphere
        // faces inwards), as well as for ReverseOrientation.
        const bool flip = reverse_orientation != (to_world.determinant3x3() < 0);
        Properties props("shape", "sphere", params.where);
        props.set("radius", float(params.get_float("radius", 1.0)), params.where);
        refuse_partial(params, "zmin", -params.get_float("radius", 1.0));
        refuse_partial(params, "zmax", params.get_float("radius", 1.0));
        refuse_partial(params, "phimax", 360.0);
        props.set("to_world", to_world, params.where);
        props.set("flip_normals", flip, params.where);
        shape = render::make_shape(props, {});
    } else if (type == "disk") {
        const double radius = params.get_float("radius", 1.0),
                     height = params.get_float("height", 0);
        if (!(radius > 0)) throw params.error("radius", "must be positive");
        refuse_partial(params, "innerradius", 0.0);
        refuse_partial(params, "phimax", 360.0);
        const bool flip = reverse_orientation != (to_world.determinant3x3() < 0);  // as sphere
        Properties props("shape", "disk", params.where);
        props.set("to_world",
                  to_world * Transform::translate(Vec3(0, 0, float(height))) *
                      Transform::scale(Vec3(float(radius), float(radius), 1)),
                  params.where);
        props.set("flip_normals", flip, params.where);
        shape = render::make_shape(props, {});
    } else if (type == "curve") {
        shape = curve_shape(params, to_world);
    } else if (type == "cylinder" || type == "loopsubdiv") {
        throw SceneError(params.where,
                         params.context() + ": shape \"" + type + "\" is not supported yet");
    } else {
        throw SceneError(params.where, params.context() + ": unknown shape \"" + type + "\"");
    }
    // `alpha` is read by the caller (the cut-out, core/shapes/alpha_cutout.h).
    params.check_all_used();
    std::vector<std::unique_ptr<Shape>> shapes;
    shapes.push_back(std::move(shape));
    if (second) shapes.push_back(std::move(second));
    return shapes;
}

}  // namespace render::pbrt
