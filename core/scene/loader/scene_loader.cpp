// Scene assembly: walks the <scene> element (and included files), builds every plugin through
// its factory, checks that every parameter was used, and fills the Scene. The accepted tags,
// plugins and parameters are documented in docs/reference/scene-format.md; keep the two in step.
// The Loader class and where each element family is read: xml_loader.h.

#include "core/scene/loader/scene_loader.h"

#include <cctype>
#include <iostream>
#include <optional>

#include "core/base/memory_budget.h"
#include "core/mesh_io/file_bytes.h"
#include "core/scene/loader/xml_loader.h"
#include "core/scene/pbrt/scene_loader.h"

namespace render::mitsuba {
namespace {

constexpr int kMaxIncludeDepth = 32;
constexpr uintmax_t kMaxSpectrumFileBytes = 16 << 20;

// Mitsuba tags this renderer knows but does not support yet.
struct Unsupported {
    const char* tag;
    const char* what;
};
constexpr Unsupported kUnsupportedTags[] = {
    {"srgb", "<srgb> colours are"},
    {"blackbody", "<blackbody> spectra are"},
    {"animation", "animated transforms (<animation>) are"},
    {"alias", "<alias> is"},
};

const char* unsupported_what(const std::string& tag) {
    for (const Unsupported& u : kUnsupportedTags)
        if (tag == u.tag) return u.what;
    return nullptr;
}

}  // namespace

void Loader::load_root(const XmlFile& file) {
    resolver_ = FileResolver(file.dir());
    include_stack_.push_back(canonical_name(file));
    read_scene_element(file);
    include_stack_.pop_back();
    if (!have_sensor_)
        throw SceneError(SourceLocation{file.name(), 0},
                         "the scene has no <sensor> (a perspective camera is required)");
}

std::string Loader::canonical_name(const XmlFile& file) {
    std::error_code ec;
    std::filesystem::path p = std::filesystem::weakly_canonical(file.name(), ec);
    return ec ? file.name() : p.string();
}

void Loader::warn(const SourceLocation& where, const std::string& message) {
    std::cerr << "warning: " << where.to_string() << ": " << message << "\n";
}

// The file a relative name in a file of folder `naming_dir` stands for (FileResolver's
// order: that folder, the main scene's folder, the <path> folders). When no candidate
// exists, the first one, so that the "not found" message names where it was expected.
std::filesystem::path Loader::resolve_file(const std::filesystem::path& name,
                                           const std::filesystem::path& naming_dir) const {
    if (std::optional<std::filesystem::path> found = resolver_.resolve(name, naming_dir))
        return *found;
    return resolver_.candidates(name, naming_dir).front();
}

// " (also looked for ...)" for a name that was not found, when there was more than one
// place to look.
std::string Loader::searched(const std::filesystem::path& name,
                             const std::filesystem::path& naming_dir) const {
    std::vector<std::filesystem::path> all = resolver_.candidates(name, naming_dir);
    if (all.size() < 2) return "";
    std::string out = " (also looked for ";
    for (size_t i = 1; i < all.size(); ++i) out += (i > 1 ? ", " : "") + all[i].string();
    return out + ")";
}

void Loader::unknown_tag(const XmlElement& e, const std::string& context) {
    const std::string tag = e.tag();
    if (const char* what = unsupported_what(tag))
        throw SceneError(e.where(), std::string(what) + " not supported yet");
    throw SceneError(e.where(), "unknown tag <" + tag + "> in " + context);
}

// Every plugin's file (meshes, environment maps, volume grids) resolves like an <include>; the
// plugin then reads the resolved path, made absolute because plugins join relative names to
// their own folder.
void Loader::resolve_filename(const XmlElement& e, Properties& props) const {
    if (const std::string* name = props.peek_string("filename"); name && !name->empty()) {
        std::filesystem::path path = resolve_file(*name, e.file().dir());
        if (confinement_.outside(path))
            throw props.error("filename", confinement_.outside_message(path));
        props.replace_string("filename", std::filesystem::absolute(path).string());
    }
}

// <spectrum name="n" filename="f.spd"/>: the file resolves and is confined as every file.
void Loader::read_spectrum_file_property(const XmlElement& e, Properties& props) {
    const std::string name = e.required("filename");
    if (name.empty()) throw SceneError(e.where(), "<spectrum>: empty filename");
    const std::filesystem::path path = resolve_file(name, e.file().dir());
    if (confinement_.outside(path))
        throw SceneError(e.where(), "<spectrum>: " + confinement_.outside_message(path));
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw SceneError(e.where(), "<spectrum>: file not found: " + path.string() +
                                        searched(name, e.file().dir()));
    if (std::filesystem::file_size(path, ec) > kMaxSpectrumFileBytes)
        throw SceneError(e.where(), "<spectrum>: " + path.string() + " is larger than " +
                                        std::to_string(kMaxSpectrumFileBytes) + " bytes");
    read_spectrum_file(e, read_file_bytes(path), path.string(), props);
}

Properties Loader::read_plain_object(const XmlElement& e, const std::string& plugin_class) {
    return read_object(e, plugin_class, [](const XmlElement&, Properties&) { return false; });
}

void Loader::register_id(const std::string& id, const SourceLocation& where) {
    auto [it, inserted] = ids_.emplace(id, where);
    if (!inserted)
        throw SceneError(
            where, "duplicate id \"" + id + "\" (first used at " + it->second.to_string() + ")");
}

void Loader::read_scene_element(const XmlFile& file) {
    XmlElement root(file.scene(), file, params_);
    // Mitsuba resolves <ref>s after the whole file is parsed, so a shape may reference a
    // named area emitter defined further down the same file (its Cornell boxes do).
    std::vector<std::string> pending_here;
    for (const XmlElement& e : root.children())
        if (is_named_area_emitter(e) && pending_area_emitters_.emplace(*e.optional("id"), e).second)
            pending_here.push_back(*e.optional("id"));
    for (const XmlElement& e : root.children()) {
        const std::string tag = e.tag();
        if (tag == "default")
            read_default(e);
        else if (tag == "include")
            read_include(e);
        else if (tag == "path")
            read_path(e);
        else if (tag == "integrator")
            read_integrator(e);
        else if (tag == "sensor")
            read_sensor(e);
        else if (tag == "bsdf")
            read_bsdf(e);
        else if (tag == "texture")
            read_texture_object(e);
        else if (tag == "shape")
            read_shape(e);
        else if (tag == "emitter")
            read_top_level_emitter(e);
        else if (tag == "medium")
            read_medium_object(e);
        else if (is_property_tag(tag))
            throw SceneError(e.where(), "property <" + tag +
                                            "> directly inside <scene> (it must belong to "
                                            "a plugin)");
        else
            unknown_tag(e, "<scene>");
    }
    for (const std::string& id : pending_here) pending_area_emitters_.erase(id);
}

void Loader::read_default(const XmlElement& e) {
    e.check_attributes({"name", "value"});
    if (!e.children().empty()) throw SceneError(e.where(), "<default> cannot have child elements");
    std::string name = e.required("name");
    if (name.empty()) throw SceneError(e.where(), "<default> has an empty name");
    for (char c : name)
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_'))
            throw SceneError(e.where(), "<default name=\"" + name +
                                            "\">: names may only contain letters, digits "
                                            "and underscores");
    std::string value = e.required("value");
    params_.emplace(name, value);  // a -D define or an earlier default wins
}

void Loader::read_include(const XmlElement& e) {
    e.check_attributes({"filename"});
    if (!e.children().empty()) throw SceneError(e.where(), "<include> cannot have child elements");
    std::filesystem::path file = e.required("filename");
    if (file.empty()) throw SceneError(e.where(), "<include>: empty filename");
    std::filesystem::path path = resolve_file(file, e.file().dir());
    if (confinement_.outside(path))
        throw SceneError(e.where(), "<include>: " + confinement_.outside_message(path));
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw SceneError(e.where(), "<include>: file not found: " + path.string() +
                                        searched(file, e.file().dir()));
    if (include_stack_.size() >= size_t(kMaxIncludeDepth))
        throw SceneError(e.where(), "<include>: includes are nested too deeply");
    std::unique_ptr<XmlFile> included;
    try {
        included = XmlFile::load(path);
    } catch (const SceneError& ex) {
        rethrow_scene_error(ex, SceneError(std::string(ex.what()) + " (included from " +
                                           e.where().to_string() + ")"));
    }
    std::string name = canonical_name(*included);
    for (const std::string& open : include_stack_)
        if (open == name)
            throw SceneError(
                e.where(), "<include>: include cycle: " + path.string() + " is already being read");
    include_stack_.push_back(name);
    read_scene_element(*included);
    include_stack_.pop_back();
}

// <path value="folder"/>: one more folder for file names to be looked up in (after the
// naming file's folder and the main scene's folder), from here on. A relative folder is
// relative to the main scene's folder. A folder that does not exist is ignored with a
// warning: a job's folder holds only the files its scene uses.
void Loader::read_path(const XmlElement& e) {
    e.check_attributes({"value"});
    if (!e.children().empty()) throw SceneError(e.where(), "<path> cannot have child elements");
    const std::string value = e.required("value");
    if (value.empty()) throw SceneError(e.where(), "<path> has an empty value");
    std::filesystem::path folder = resolver_.search_folder(value);
    if (confinement_.outside(folder))
        throw SceneError(e.where(), "<path>: " + confinement_.outside_message(folder));
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec))
        warn(e.where(), "<path>: folder not found: " + folder.string());
    resolver_.add_search_path(folder);
}

void Loader::read_integrator(const XmlElement& e) {
    if (have_integrator_)
        throw SceneError(e.where(), "only one <integrator> is allowed (first at " +
                                        integrator_where_.to_string() + ")");
    read_integrator_object(e);
    have_integrator_ = true;
    integrator_where_ = e.where();
}

// An <integrator> only chooses the default algorithm (render --algo overrides it) and the
// path depths. Integrators that wrap others (Mitsuba's moment, aov, stokes, ...) are looked
// through: the innermost one (the first nested at each level) names the algorithm and
// gives max_depth and rr_depth. Every other parameter, and every further nested integrator,
// is ignored with a warning; which type names an algorithm is for the renderer to decide.
void Loader::read_integrator_object(const XmlElement& e) {
    std::optional<XmlElement> inner;
    Properties props = read_object(e, "integrator", [&](const XmlElement& c, Properties&) {
        if (c.tag() != "integrator") return false;
        if (inner)
            warn(c.where(), "only the first integrator nested in integrator \"" +
                                e.required("type") + "\" is used; this one is ignored");
        else
            inner = c;
        return true;
    });
    if (props.type().empty()) throw SceneError(e.where(), "empty integrator type");
    auto warn_unused = [&] {
        for (const auto& [name, where] : props.unused())
            warn(where, "integrator \"" + props.type() + "\": parameter \"" + name +
                            "\" is ignored (the algorithm and its options come from "
                            "the renderer)");
        props.mark_all_used();
    };
    if (inner) {
        warn(e.where(), "integrator \"" + props.type() +
                            "\" wraps another; its own effect is ignored and the nested "
                            "integrator is used");
        warn_unused();
        read_integrator_object(*inner);
        return;
    }
    build(props, [&] {
        SceneSettings& s = scene_.settings;
        s.integrator = props.type();
        int64_t max_depth = props.get_int("max_depth", s.max_depth);
        if (max_depth < -1 || max_depth > 1000000)
            throw props.error("max_depth", "must be -1 (unbounded) or a non-negative depth");
        int64_t rr_depth = props.get_int("rr_depth", s.rr_depth);
        if (rr_depth < 1 || rr_depth > 1000000) throw props.error("rr_depth", "must be positive");
        s.max_depth = int(max_depth);
        s.rr_depth = int(rr_depth);
        warn_unused();
        return 0;
    });
}

}  // namespace render::mitsuba

namespace render {
namespace {

std::unique_ptr<Scene> load(const XmlFile& file, const std::map<std::string, std::string>& defines,
                            const std::string& source_file,
                            const std::filesystem::path& confine_to) {
    auto scene = std::make_unique<Scene>();
    scene->source_file = source_file;
    try {
        mitsuba::Loader(*scene, defines, confine_to).load_root(file);
        scene->commit();
    } catch (const SceneError&) {
        throw;
    } catch (const std::exception& ex) {
        throw SceneError(SourceLocation{file.name(), 0}, ex.what());
    }
    return scene;
}

}  // namespace

std::unique_ptr<Scene> load_scene(const std::filesystem::path& file,
                                  const std::map<std::string, std::string>& defines,
                                  const std::filesystem::path& confine_to) {
    if (file.extension() == ".pbrt") {
        // pbrt-v4 files have no $name parameters.
        if (!defines.empty())
            throw SceneError(SourceLocation{file.string(), 0},
                             "-D " + defines.begin()->first +
                                 "=...: pbrt files take no parameters (defines are for Mitsuba "
                                 "files)");
        return pbrt::load_scene(file, confine_to);
    }
    std::unique_ptr<XmlFile> xml = XmlFile::load(file);
    return load(*xml, defines, file.string(), confine_to);
}

std::unique_ptr<Scene> load_scene_from_string(const std::string& xml,
                                              const std::filesystem::path& base_dir,
                                              const std::map<std::string, std::string>& defines) {
    XmlFile file(xml, "<string>", base_dir.empty() ? std::filesystem::path(".") : base_dir);
    return load(file, defines, "<string>", {});
}

}  // namespace render
