#include "core/mesh_io/obj_reader.h"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <map>
#include <tuple>
#include <vector>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/mesh_io/file_bytes.h"
#include "core/mesh_io/mesh_limits.h"

namespace render {
namespace {

struct FaceVertex {
    int64_t v = -1, t = -1, n = -1;  // zero-based; -1 = absent
};

std::vector<std::string_view> split_words(std::string_view line) {
    std::vector<std::string_view> words;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
        size_t start = i;
        while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
        if (i > start) words.push_back(line.substr(start, i - start));
    }
    return words;
}

class ObjParser {
  public:
    explicit ObjParser(const std::string& name) : name_(name) {}

    MeshData parse(std::string_view text) {
        size_t pos = 0;
        int line_no = 0;
        std::string joined;
        while (pos < text.size()) {
            size_t eol = text.find('\n', pos);
            if (eol == std::string_view::npos) eol = text.size();
            std::string_view line = text.substr(pos, eol - pos);
            pos = eol + 1;
            ++line_no;
            line_ = line_no;
            // A trailing backslash continues the statement on the next line.
            joined.clear();
            while (true) {
                std::string_view l = line;
                while (!l.empty() && (l.back() == '\r' || l.back() == ' ' || l.back() == '\t'))
                    l.remove_suffix(1);
                if (l.empty() || l.back() != '\\' || pos >= text.size()) {
                    joined.append(l);
                    break;
                }
                l.remove_suffix(1);
                joined.append(l);
                joined.push_back(' ');
                eol = text.find('\n', pos);
                if (eol == std::string_view::npos) eol = text.size();
                line = text.substr(pos, eol - pos);
                pos = eol + 1;
                ++line_no;
            }
            size_t hash = joined.find('#');
            std::string_view statement(joined);
            if (hash != std::string::npos) statement = statement.substr(0, hash);
            statement_(statement);
        }
        return build();
    }

  private:
    SceneError error(const std::string& msg) const {
        return SceneError(name_ + ":" + std::to_string(line_) + ": " + msg);
    }

    float number(std::string_view s, const char* what) const {
        const char* first = s.data();
        const char* last = s.data() + s.size();
        if (first != last && *first == '+') ++first;
        double v = 0;
        auto [p, ec] = std::from_chars(first, last, v);
        if (ec != std::errc() && ec != std::errc::result_out_of_range)
            throw error(std::string(what) + ": \"" + std::string(s) + "\" is not a number");
        if (p != last)
            throw error(std::string(what) + ": \"" + std::string(s) + "\" is not a number");
        float f = float(v);
        if (ec == std::errc::result_out_of_range || !std::isfinite(f))
            throw error(std::string(what) + ": \"" + std::string(s) + "\" is not finite");
        return f;
    }

    // Resolves a 1-based or negative (relative) index into [0, count).
    int64_t index(std::string_view s, size_t count, const char* what) const {
        const char* first = s.data();
        const char* last = s.data() + s.size();
        if (first != last && *first == '+') ++first;
        int64_t i = 0;
        auto [p, ec] = std::from_chars(first, last, i);
        if (ec != std::errc() || p != last || s.empty())
            throw error(std::string("face: bad ") + what + " index \"" + std::string(s) + "\"");
        if (i == 0) throw error(std::string("face: ") + what + " index 0 (OBJ indices start at 1)");
        int64_t resolved = i > 0 ? i - 1 : int64_t(count) + i;
        if (resolved < 0 || resolved >= int64_t(count))
            throw error(std::string("face: ") + what + " index " + std::to_string(i) +
                        " out of range (" + std::to_string(count) + " defined so far)");
        return resolved;
    }

    void statement_(std::string_view statement) {
        std::vector<std::string_view> w = split_words(statement);
        if (w.empty()) return;
        std::string_view key = w[0];
        if (key == "v") {
            if (w.size() < 4 || w.size() > 8)
                throw error("v needs 3 coordinates (optionally w or a colour)");
            positions_.emplace_back(number(w[1], "v"), number(w[2], "v"), number(w[3], "v"));
            for (size_t i = 4; i < w.size(); ++i) number(w[i], "v");
        } else if (key == "vn") {
            if (w.size() != 4) throw error("vn needs 3 coordinates");
            normals_.emplace_back(number(w[1], "vn"), number(w[2], "vn"), number(w[3], "vn"));
        } else if (key == "vt") {
            if (w.size() < 2 || w.size() > 4) throw error("vt needs 1 to 3 coordinates");
            float u = number(w[1], "vt");
            float v = w.size() > 2 ? number(w[2], "vt") : 0.0f;
            if (w.size() > 3) number(w[3], "vt");
            uvs_.emplace_back(u, v);
        } else if (key == "f") {
            if (w.size() < 4) throw error("a face needs at least 3 vertices");
            std::vector<FaceVertex> polygon;
            for (size_t i = 1; i < w.size(); ++i) polygon.push_back(face_vertex(w[i]));
            for (size_t i = 1; i + 1 < polygon.size(); ++i) {
                corners_.push_back(polygon[0]);
                corners_.push_back(polygon[i]);
                corners_.push_back(polygon[i + 1]);
            }
            if (corners_.size() / 3 >= charged_triangles_ + kChargeBatch) charge_triangles();
        }
        // Everything else (o, g, s, usemtl, mtllib, l, p, vp, curves...) does not matter here.
    }

    FaceVertex face_vertex(std::string_view s) const {
        FaceVertex fv;
        size_t slash1 = s.find('/');
        if (slash1 == std::string_view::npos) {
            fv.v = index(s, positions_.size(), "position");
            return fv;
        }
        fv.v = index(s.substr(0, slash1), positions_.size(), "position");
        std::string_view rest = s.substr(slash1 + 1);
        size_t slash2 = rest.find('/');
        std::string_view t = slash2 == std::string_view::npos ? rest : rest.substr(0, slash2);
        if (!t.empty()) fv.t = index(t, uvs_.size(), "texture coordinate");
        if (slash2 != std::string_view::npos) {
            std::string_view n = rest.substr(slash2 + 1);
            if (n.find('/') != std::string_view::npos)
                throw error("face: bad vertex \"" + std::string(s) + "\"");
            fv.n = index(n, normals_.size(), "normal");
        } else if (t.empty()) {
            throw error("face: bad vertex \"" + std::string(s) + "\"");
        }
        return fv;
    }

    // Checks the triangles parsed so far against the mesh limit and charges the scene's memory
    // budget with them (their corners here and the mesh they become), in batches: a short
    // polygon line gives many corners, so the text's size alone does not bound them well.
    static constexpr uint64_t kChargeBatch = 1 << 16;
    void charge_triangles() {
        const uint64_t triangles = corners_.size() / 3;
        check_mesh_counts(name_, positions_.size(), triangles);
        charge_scene_memory((triangles - charged_triangles_) * (3 * sizeof(FaceVertex)) +
                                mesh_triangle_bytes(triangles - charged_triangles_),
                            name_ + ":" + std::to_string(line_) + ": faces");
        charged_triangles_ = triangles;
    }

    MeshData build() {
        charge_triangles();
        bool all_n = !corners_.empty(), all_t = !corners_.empty();
        for (const FaceVertex& c : corners_) {
            all_n = all_n && c.n >= 0;
            all_t = all_t && c.t >= 0;
        }
        MeshData mesh;
        std::map<std::tuple<int64_t, int64_t, int64_t>, uint32_t> unique;
        mesh.indices.reserve(corners_.size());
        for (const FaceVertex& c : corners_) {
            auto key = std::make_tuple(c.v, all_t ? c.t : -1, all_n ? c.n : -1);
            auto [it, inserted] = unique.emplace(key, uint32_t(mesh.positions.size()));
            if (inserted) {
                mesh.positions.push_back(positions_[size_t(c.v)]);
                if (all_n) mesh.normals.push_back(normals_[size_t(c.n)]);
                if (all_t) mesh.uvs.push_back(uvs_[size_t(c.t)]);
            }
            mesh.indices.push_back(it->second);
        }
        check_mesh_counts(name_, mesh.positions.size(), mesh.indices.size() / 3);
        charge_scene_memory(mesh_vertex_bytes(mesh.positions.size(), all_n, all_t),
                            name_ + ": vertices");
        return mesh;
    }

    const std::string& name_;
    int line_ = 0;
    std::vector<Vec3> positions_, normals_;
    std::vector<Vec2> uvs_;
    std::vector<FaceVertex> corners_;  // 3 per triangle
    uint64_t charged_triangles_ = 0;   // triangles charged to the memory budget
};

}  // namespace

MeshData read_obj_from_memory(std::string_view text, const std::string& name) {
    return ObjParser(name).parse(text);
}

MeshData read_obj(const std::filesystem::path& path) {
    std::string text = read_file_bytes(path);
    return read_obj_from_memory(text, path.string());
}

}  // namespace render
