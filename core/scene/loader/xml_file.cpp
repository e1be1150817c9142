#include "core/scene/loader/xml_file.h"

#include <algorithm>
#include <charconv>

#include "core/mesh_io/file_bytes.h"
#include "core/scene/loader/version_upgrade.h"

namespace render {
namespace {

constexpr int kMaxDepth = 64;

bool parse_version(const std::string& s, FormatVersion& out) {
    const char* p = s.data();
    const char* end = s.data() + s.size();
    for (int i = 0; i < 3; ++i) {
        auto [q, ec] = std::from_chars(p, end, out.v[size_t(i)]);
        if (ec != std::errc() || out.v[size_t(i)] < 0) return false;
        p = q;
        if (i < 2) {
            if (p == end || *p != '.') return false;
            ++p;
        }
    }
    return p == end;
}

}  // namespace

std::string FormatVersion::to_string() const {
    return std::to_string(v[0]) + "." + std::to_string(v[1]) + "." + std::to_string(v[2]);
}

XmlFile::XmlFile(std::string text, std::string display_name, std::filesystem::path dir)
    : name_(std::move(display_name)), dir_(std::move(dir)) {
    line_starts_.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
        if (text[i] == '\n') line_starts_.push_back(i + 1);

    pugi::xml_parse_result result =
        doc_.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!result)
        throw SceneError(where_offset(result.offset),
                         std::string("malformed XML: ") + result.description());

    pugi::xml_node root;
    for (pugi::xml_node n : doc_.children()) {
        if (n.type() == pugi::node_pcdata || n.type() == pugi::node_cdata)
            throw SceneError(where(n), "text outside the <scene> element");
        if (n.type() != pugi::node_element) continue;
        if (root) throw SceneError(where(n), "a scene file has exactly one root element");
        root = n;
    }
    if (!root) throw SceneError(SourceLocation{name_, 0}, "no <scene> element");
    if (std::string(root.name()) != "scene")
        throw SceneError(where(root), "the root element must be <scene>, not <" +
                                          std::string(root.name()) + ">");
    for (pugi::xml_attribute a : root.attributes())
        if (std::string(a.name()) != "version")
            throw SceneError(where(root),
                             "unknown attribute \"" + std::string(a.name()) + "\" on <scene>");
    pugi::xml_attribute version = root.attribute("version");
    if (!version)
        throw SceneError(where(root), "<scene> needs a version attribute (e.g. \"3.0.0\")");
    if (!parse_version(version.value(), version_))
        throw SceneError(where(root), "scene version \"" + std::string(version.value()) +
                                          "\" is not of the form major.minor.patch");
    if (version_.v[0] > 3)
        throw SceneError(where(root), "scene version " + version_.to_string() +
                                          " is newer than the supported 3.x format");
    // Everything below recurses over the element tree: bound its depth first.
    struct DepthWalker : pugi::xml_tree_walker {
        pugi::xml_node too_deep;
        bool for_each(pugi::xml_node& node) override {
            if (depth() < kMaxDepth) return true;
            too_deep = node;
            return false;
        }
    } walker;
    root.traverse(walker);
    if (walker.too_deep)
        throw SceneError(where(walker.too_deep), "elements are nested too deeply (more than " +
                                                     std::to_string(kMaxDepth) + " levels)");
    scene_ = root;
    upgrade_scene(scene_, version_);
}

std::unique_ptr<XmlFile> XmlFile::load(const std::filesystem::path& path) {
    std::string text = read_file_bytes(path);
    std::filesystem::path dir = path.parent_path();
    if (dir.empty()) dir = ".";
    return std::make_unique<XmlFile>(std::move(text), path.string(), dir);
}

SourceLocation XmlFile::where_offset(ptrdiff_t offset) const {
    if (offset < 0) return SourceLocation{name_, 0};
    auto it = std::upper_bound(line_starts_.begin(), line_starts_.end(), size_t(offset));
    return SourceLocation{name_, int(it - line_starts_.begin())};
}

SourceLocation XmlFile::where(pugi::xml_node node) const {
    return where_offset(node.offset_debug());
}

}  // namespace render
