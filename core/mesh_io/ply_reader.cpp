#include "core/mesh_io/ply_reader.h"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <vector>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/mesh_io/file_bytes.h"
#include "core/mesh_io/mesh_limits.h"

namespace render {
namespace {

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::optional<PlyType> parse_type(const std::string& s) {
    if (s == "char" || s == "int8") return PlyType::Int8;
    if (s == "uchar" || s == "uint8") return PlyType::UInt8;
    if (s == "short" || s == "int16") return PlyType::Int16;
    if (s == "ushort" || s == "uint16") return PlyType::UInt16;
    if (s == "int" || s == "int32") return PlyType::Int32;
    if (s == "uint" || s == "uint32") return PlyType::UInt32;
    if (s == "float" || s == "float32") return PlyType::Float32;
    if (s == "double" || s == "float64") return PlyType::Float64;
    return std::nullopt;
}

size_t type_size(PlyType t) {
    switch (t) {
        case PlyType::Int8:
        case PlyType::UInt8:
            return 1;
        case PlyType::Int16:
        case PlyType::UInt16:
            return 2;
        case PlyType::Int32:
        case PlyType::UInt32:
        case PlyType::Float32:
            return 4;
        case PlyType::Float64:
            return 8;
    }
    return 1;
}

bool is_integral(PlyType t) {
    return t != PlyType::Float32 && t != PlyType::Float64;
}

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::Float32;  // item type for lists
    bool is_list = false;
    PlyType count_type = PlyType::UInt8;
};

struct PlyElement {
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> properties;
};

enum class Format { Ascii, BinaryLittle, BinaryBig };

std::vector<std::string> split_words(std::string_view line) {
    std::vector<std::string> words;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
        size_t start = i;
        while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
        if (i > start) words.emplace_back(line.substr(start, i - start));
    }
    return words;
}

// Binary values, bounds-checked.
class BinaryCursor {
  public:
    BinaryCursor(std::string_view data, size_t pos, bool big_endian, const std::string& name)
        : data_(data),
          pos_(pos),
          swap_(big_endian != (std::endian::native == std::endian::big)),
          name_(name) {}

    void set_context(const std::string* element, uint64_t index) {
        element_ = element, index_ = index;
    }
    size_t remaining() const { return data_.size() - pos_; }

    double read(PlyType t) {
        size_t n = type_size(t);
        if (remaining() < n)
            throw SceneError(name_ + ": " + *element_ + " " + std::to_string(index_) +
                             ": file is truncated (ends at byte " + std::to_string(data_.size()) +
                             ")");
        unsigned char b[8];
        std::memcpy(b, data_.data() + pos_, n);
        pos_ += n;
        if (swap_)
            for (size_t i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
        switch (t) {
            case PlyType::Int8:
                return double(int8_t(b[0]));
            case PlyType::UInt8:
                return double(b[0]);
            case PlyType::Int16:
                return double(load<int16_t>(b));
            case PlyType::UInt16:
                return double(load<uint16_t>(b));
            case PlyType::Int32:
                return double(load<int32_t>(b));
            case PlyType::UInt32:
                return double(load<uint32_t>(b));
            case PlyType::Float32:
                return double(load<float>(b));
            case PlyType::Float64:
                return load<double>(b);
        }
        return 0;
    }
    std::string where() const { return name_ + ": " + *element_ + " " + std::to_string(index_); }

  private:
    template <typename T>
    static T load(const unsigned char* b) {
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
    std::string_view data_;
    size_t pos_;
    bool swap_;
    const std::string& name_;
    const std::string* element_ = nullptr;
    uint64_t index_ = 0;
};

// ASCII values: whitespace-separated tokens, with line numbers for messages.
class AsciiCursor {
  public:
    AsciiCursor(std::string_view data, size_t pos, int line, const std::string& name)
        : data_(data), pos_(pos), line_(line), name_(name) {}

    void set_context(const std::string* element, uint64_t index) {
        element_ = element, index_ = index;
    }
    // A lower bound on the values left (each needs at least two characters but the last).
    size_t remaining() const { return (data_.size() - pos_) / 2 + 1; }

    double read(PlyType t) {
        skip_space();
        if (pos_ >= data_.size()) {
            token_line_ = line_;
            throw SceneError(where() + ": file is truncated (expected more values)");
        }
        size_t start = pos_;
        token_line_ = line_;
        while (pos_ < data_.size() && !is_space(data_[pos_])) ++pos_;
        std::string_view token = data_.substr(start, pos_ - start);
        const char* first = token.data();
        const char* last = token.data() + token.size();
        if (first != last && *first == '+') ++first;
        if (is_integral(t)) {
            int64_t v = 0;
            auto [p, ec] = std::from_chars(first, last, v);
            if (ec != std::errc() || p != last)
                throw SceneError(where() + ": \"" + std::string(token) + "\" is not an integer");
            return double(v);
        }
        double v = 0;
        auto [p, ec] = std::from_chars(first, last, v);
        if (ec == std::errc::result_out_of_range)
            v = HUGE_VAL;  // reported as non-finite
        else if (ec != std::errc() || p != last)
            throw SceneError(where() + ": \"" + std::string(token) + "\" is not a number");
        return v;
    }
    // The line of the value read last.
    std::string where() const {
        return name_ + ":" + std::to_string(token_line_) + ": " + *element_ + " " +
               std::to_string(index_);
    }
    bool at_end() {
        skip_space();
        return pos_ >= data_.size();
    }
    int line() {
        skip_space();
        return line_;
    }

  private:
    static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
    void skip_space() {
        while (pos_ < data_.size() && is_space(data_[pos_])) {
            if (data_[pos_] == '\n') ++line_;
            ++pos_;
        }
    }
    std::string_view data_;
    size_t pos_;
    int line_;
    int token_line_ = 0;
    const std::string& name_;
    const std::string* element_ = nullptr;
    uint64_t index_ = 0;
};

struct Header {
    Format format = Format::Ascii;
    std::vector<PlyElement> elements;
    size_t body_offset = 0;
    int body_line = 1;  // line number of the first body line (ASCII)
};

Header parse_header(std::string_view data, const std::string& name) {
    Header h;
    size_t pos = 0;
    int line_no = 0;
    bool have_format = false;
    auto fail = [&](const std::string& msg) -> SceneError {
        return SceneError(name + ":" + std::to_string(line_no) + ": " + msg);
    };
    while (true) {
        if (pos >= data.size()) {
            line_no++;
            throw fail("header is truncated (no end_header)");
        }
        size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) eol = data.size();
        std::string_view line = data.substr(pos, eol - pos);
        pos = eol + 1;
        ++line_no;
        if (line.size() > 4096) throw fail("header line too long (not a PLY file?)");
        std::vector<std::string> w = split_words(line);
        if (line_no == 1) {
            if (w.size() != 1 || w[0] != "ply") throw fail("not a PLY file (no \"ply\" magic)");
            continue;
        }
        if (w.empty()) continue;
        const std::string& key = w[0];
        if (key == "comment" || key == "obj_info") continue;
        if (key == "format") {
            if (w.size() != 3) throw fail("malformed format line");
            if (w[1] == "ascii")
                h.format = Format::Ascii;
            else if (w[1] == "binary_little_endian")
                h.format = Format::BinaryLittle;
            else if (w[1] == "binary_big_endian")
                h.format = Format::BinaryBig;
            else
                throw fail("unknown format \"" + w[1] + "\"");
            if (w[2] != "1.0") throw fail("unsupported PLY version \"" + w[2] + "\"");
            have_format = true;
        } else if (key == "element") {
            if (w.size() != 3) throw fail("malformed element line");
            PlyElement e;
            e.name = w[1];
            uint64_t count = 0;
            auto [p, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), count);
            if (ec != std::errc() || p != w[2].data() + w[2].size())
                throw fail("element \"" + w[1] + "\": bad count \"" + w[2] + "\"");
            e.count = count;
            for (const PlyElement& other : h.elements)
                if (other.name == e.name) throw fail("element \"" + e.name + "\" given twice");
            h.elements.push_back(std::move(e));
        } else if (key == "property") {
            if (h.elements.empty()) throw fail("property before any element");
            PlyProperty prop;
            if (w.size() >= 2 && w[1] == "list") {
                if (w.size() != 5) throw fail("malformed list property line");
                auto count_type = parse_type(w[2]);
                auto item_type = parse_type(w[3]);
                if (!count_type || !item_type)
                    throw fail("unknown property type in list \"" + w[4] + "\"");
                if (!is_integral(*count_type))
                    throw fail("list \"" + w[4] + "\" has a non-integer count type");
                prop.is_list = true;
                prop.count_type = *count_type;
                prop.type = *item_type;
                prop.name = w[4];
            } else {
                if (w.size() != 3) throw fail("malformed property line");
                auto type = parse_type(w[1]);
                if (!type) throw fail("unknown property type \"" + w[1] + "\"");
                prop.type = *type;
                prop.name = w[2];
            }
            for (const PlyProperty& other : h.elements.back().properties)
                if (other.name == prop.name)
                    throw fail("property \"" + prop.name + "\" given twice");
            h.elements.back().properties.push_back(std::move(prop));
        } else if (key == "end_header") {
            if (w.size() != 1) throw fail("malformed end_header line");
            break;
        } else {
            throw fail("unknown header keyword \"" + key + "\"");
        }
    }
    if (!have_format) throw fail("header has no format line");
    h.body_offset = std::min(pos, data.size());
    h.body_line = line_no + 1;
    return h;
}

int find_property(const PlyElement& e, std::initializer_list<const char*> names) {
    for (const char* n : names)
        for (size_t i = 0; i < e.properties.size(); ++i)
            if (!e.properties[i].is_list && e.properties[i].name == n) return int(i);
    return -1;
}

template <typename Cursor>
MeshData read_body(Cursor& in, const Header& h, const std::string& name,
                   std::vector<PlyQuad>* quads) {
    MeshData mesh;
    const PlyElement* vertex = nullptr;
    const PlyElement* face = nullptr;
    for (const PlyElement& e : h.elements) {
        if (e.name == "vertex") vertex = &e;
        if (e.name == "face") face = &e;
    }
    if (!vertex) throw SceneError(name + ": no \"vertex\" element");
    int ix = find_property(*vertex, {"x"}), iy = find_property(*vertex, {"y"}),
        iz = find_property(*vertex, {"z"});
    if (ix < 0 || iy < 0 || iz < 0)
        throw SceneError(name + ": the vertex element needs properties x, y and z");
    int inx = find_property(*vertex, {"nx"}), iny = find_property(*vertex, {"ny"}),
        inz = find_property(*vertex, {"nz"});
    bool has_normals = inx >= 0 && iny >= 0 && inz >= 0;
    int iu = find_property(*vertex, {"u", "s", "texture_u", "texture_s"});
    int iv = find_property(*vertex, {"v", "t", "texture_v", "texture_t"});
    bool has_uvs = iu >= 0 && iv >= 0;
    int face_list = -1;
    if (face) {
        for (size_t i = 0; i < face->properties.size(); ++i)
            if (face->properties[i].is_list && (face->properties[i].name == "vertex_indices" ||
                                                face->properties[i].name == "vertex_index"))
                face_list = int(i);
        if (face_list < 0)
            throw SceneError(name + ": the face element needs a list property vertex_indices");
        if (!is_integral(face->properties[size_t(face_list)].type))
            throw SceneError(name + ": vertex_indices must have an integer type");
    }
    const uint64_t vertex_count = vertex->count;
    check_mesh_counts(name, vertex_count, face ? face->count : 0);

    std::vector<double> values;
    for (const PlyElement& e : h.elements) {
        if (e.properties.empty()) continue;  // nothing to read, however large the count
        // Never trust the header's counts for allocation: at most what the data can hold.
        size_t min_record = 0;
        for (const PlyProperty& p : e.properties)
            min_record += p.is_list ? type_size(p.count_type) : type_size(p.type);
        size_t plausible = min_record ? in.remaining() / min_record + 1 : 0;
        bool is_vertex = &e == vertex, is_face = &e == face;
        if (is_vertex) {
            size_t n = size_t(std::min<uint64_t>(e.count, plausible));
            charge_scene_memory(mesh_vertex_bytes(n, has_normals, has_uvs), name + ": vertices");
            mesh.positions.reserve(n);
            if (has_normals) mesh.normals.reserve(n);
            if (has_uvs) mesh.uvs.reserve(n);
        }
        if (is_face) {
            const size_t n = size_t(std::min<uint64_t>(e.count, plausible));
            charge_scene_memory(mesh_triangle_bytes(n), name + ": faces");
            mesh.indices.reserve(3 * n);
        }
        values.assign(e.properties.size(), 0.0);
        std::vector<uint32_t> polygon;
        for (uint64_t k = 0; k < e.count; ++k) {
            in.set_context(&e.name, k);
            for (size_t pi = 0; pi < e.properties.size(); ++pi) {
                const PlyProperty& p = e.properties[pi];
                if (!p.is_list) {
                    values[pi] = in.read(p.type);
                    continue;
                }
                double count = in.read(p.count_type);
                if (count < 0)
                    throw SceneError(in.where() + ": negative list length in \"" + p.name + "\"");
                bool is_index_list = is_face && int(pi) == face_list;
                if (is_index_list) {
                    if (count < 3)
                        throw SceneError(in.where() + ": a face needs at least 3 vertices (has " +
                                         std::to_string(int64_t(count)) + ")");
                    polygon.clear();
                }
                for (uint64_t j = 0; j < uint64_t(count); ++j) {
                    double v = in.read(p.type);
                    if (!is_index_list) continue;
                    if (v < 0 || v >= double(vertex_count))
                        throw SceneError(in.where() + ": vertex index " +
                                         std::to_string(int64_t(v)) + " out of range (" +
                                         std::to_string(vertex_count) + " vertices)");
                    polygon.push_back(uint32_t(v));
                }
                // A polygon of n vertices gives n - 2 triangles: more triangles than faces.
                if (is_index_list)
                    check_mesh_counts(name, vertex_count,
                                      mesh.indices.size() / 3 + polygon.size() - 2);
                if (is_index_list && quads && polygon.size() == 4)
                    quads->push_back(PlyQuad{{polygon[0], polygon[1], polygon[2], polygon[3]},
                                             mesh.indices.size() / 3});
                if (is_index_list)
                    for (size_t j = 1; j + 1 < polygon.size(); ++j)
                        mesh.indices.insert(mesh.indices.end(),
                                            {polygon[0], polygon[j], polygon[j + 1]});
            }
            if (is_vertex) {
                Vec3 pos{float(values[size_t(ix)]), float(values[size_t(iy)]),
                         float(values[size_t(iz)])};
                if (!is_finite(pos)) throw SceneError(in.where() + ": non-finite vertex position");
                mesh.positions.push_back(pos);
                if (has_normals)
                    mesh.normals.emplace_back(float(values[size_t(inx)]),
                                              float(values[size_t(iny)]),
                                              float(values[size_t(inz)]));
                if (has_uvs)
                    mesh.uvs.emplace_back(float(values[size_t(iu)]), float(values[size_t(iv)]));
            }
        }
    }
    return mesh;
}

}  // namespace

MeshData read_ply_from_memory(std::string_view bytes, const std::string& name,
                              std::vector<PlyQuad>* quads) {
    Header h = parse_header(bytes, name);
    if (h.format == Format::Ascii) {
        AsciiCursor in(bytes, h.body_offset, h.body_line, name);
        MeshData mesh = read_body(in, h, name, quads);
        if (!in.at_end())
            throw SceneError(name + ":" + std::to_string(in.line()) +
                             ": unexpected data after the last element");
        return mesh;
    }
    BinaryCursor in(bytes, h.body_offset, h.format == Format::BinaryBig, name);
    return read_body(in, h, name, quads);
}

MeshData read_ply(const std::filesystem::path& path, std::vector<PlyQuad>* quads) {
    std::string bytes = read_file_bytes(path);
    return read_ply_from_memory(bytes, path.string(), quads);
}

}  // namespace render
