// Scene assembly: walks the <scene> element (and included files), builds every plugin through
// its factory, checks that every parameter was used, and fills the Scene. The accepted tags,
// plugins and parameters are documented in docs/scene-format.md; keep the two in step.

#include "core/scene/loader/scene_loader.h"
#include "core/base/memory_budget.h"

#include <cctype>
#include <cmath>
#include <iostream>
#include <optional>
#include <set>

#include "core/lights/light_factory.h"
#include "core/materials/bsdf_factory.h"
#include "core/media/medium_factory.h"
#include "core/media/volume_factory.h"
#include "core/mesh_io/file_bytes.h"
#include "core/scene/loader/file_resolver.h"
#include "core/scene/loader/property_reader.h"
#include "core/scene/loader/shape_factory.h"
#include "core/scene/loader/values.h"
#include "core/scene/loader/xml_element.h"
#include "core/scene/loader/xml_file.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/shapes/instance.h"
#include "core/textures/texture_factory.h"

namespace render {
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

// Known sampler plugins; all are rendered with independent samples.
constexpr const char* kSamplerTypes[] = {"independent", "stratified", "multijitter", "orthogonal",
                                         "ldsampler",   "halton",     "sobol"};

class Loader {
  public:
    Loader(Scene& scene, const std::map<std::string, std::string>& defines,
           const std::filesystem::path& confine_to)
        : scene_(scene),
          params_(defines.begin(), defines.end()),
          resolver_("."),
          confined_(!confine_to.empty()),
          confine_root_(confined_ ? canonical_path(confine_to) : std::filesystem::path()) {}

    void load_root(const XmlFile& file) {
        resolver_ = FileResolver(file.dir());
        include_stack_.push_back(canonical_name(file));
        read_scene_element(file);
        include_stack_.pop_back();
        if (!have_sensor_)
            throw SceneError(SourceLocation{file.name(), 0},
                             "the scene has no <sensor> (a perspective camera is required)");
    }

  private:
    // ----- generic helpers -----

    static std::string canonical_name(const XmlFile& file) {
        std::error_code ec;
        std::filesystem::path p = std::filesystem::weakly_canonical(file.name(), ec);
        return ec ? file.name() : p.string();
    }

    static std::filesystem::path canonical_path(const std::filesystem::path& p) {
        std::error_code ec;
        std::filesystem::path c = std::filesystem::weakly_canonical(p, ec);
        return ec ? std::filesystem::absolute(p).lexically_normal() : c;
    }

    // With a `confine_to` folder, `path` (a file or a <path> folder) must lie inside it.
    bool outside_scene_folder(const std::filesystem::path& path) const {
        if (!confined_) return false;
        const std::string rel =
            canonical_path(path).lexically_relative(confine_root_).generic_string();
        return rel.empty() || rel == ".." || rel.rfind("../", 0) == 0;
    }
    std::string outside_message(const std::filesystem::path& path) const {
        return path.string() + " is outside " + confine_root_.string() +
               " (a job reads only the files of its bundle)";
    }

    static void warn(const SourceLocation& where, const std::string& message) {
        std::cerr << "warning: " << where.to_string() << ": " << message << "\n";
    }

    // The file a relative name in a file of folder `naming_dir` stands for (FileResolver's
    // order: that folder, the main scene's folder, the <path> folders). When no candidate
    // exists, the first one, so that the "not found" message names where it was expected.
    std::filesystem::path resolve_file(const std::filesystem::path& name,
                                       const std::filesystem::path& naming_dir) const {
        if (std::optional<std::filesystem::path> found = resolver_.resolve(name, naming_dir))
            return *found;
        return resolver_.candidates(name, naming_dir).front();
    }

    // " (also looked for ...)" for a name that was not found, when there was more than one
    // place to look.
    std::string searched(const std::filesystem::path& name,
                         const std::filesystem::path& naming_dir) const {
        std::vector<std::filesystem::path> all = resolver_.candidates(name, naming_dir);
        if (all.size() < 2) return "";
        std::string out = " (also looked for ";
        for (size_t i = 1; i < all.size(); ++i) out += (i > 1 ? ", " : "") + all[i].string();
        return out + ")";
    }

    [[noreturn]] static void unknown_tag(const XmlElement& e, const std::string& context) {
        const std::string tag = e.tag();
        if (const char* what = unsupported_what(tag))
            throw SceneError(e.where(), std::string(what) + " not supported yet");
        throw SceneError(e.where(), "unknown tag <" + tag + "> in " + context);
    }

    // Builds a plugin through a factory, turning any non-SceneError exception into a located
    // SceneError; then checks that every parameter was used.
    template <typename F>
    static auto build(const Properties& props, F&& factory) {
        try {
            auto result = factory();
            props.check_all_used();
            return result;
        } catch (const SceneError&) {
            throw;
        } catch (const std::exception& ex) {
            throw SceneError(props.where(),
                             props.plugin_class() + " \"" + props.type() + "\": " + ex.what());
        }
    }

    // Reads an object element: its type, id, property children; other children go to
    // `on_child`, which returns false for tags it does not accept.
    template <typename OnChild>
    Properties read_object(const XmlElement& e, const std::string& plugin_class,
                           OnChild&& on_child) {
        e.check_attributes({"type", "id", "name"});
        std::string type = e.required("type");
        Properties props(plugin_class, type, e.where());
        if (std::optional<std::string> id = e.optional("id")) {
            if (id->empty()) throw SceneError(e.where(), "empty id on " + e.describe());
            props.id = *id;
        }
        for (const XmlElement& child : e.children()) {
            if (child.tag() == "spectrum" && child.has("filename")) {
                read_spectrum_file_property(child, props);
            } else if (is_property_tag(child.tag())) {
                read_property(child, props);
            } else if (!on_child(child, props)) {
                unknown_tag(child, e.describe());
            }
        }
        // Every plugin's file (meshes, environment maps, volume grids) resolves like an
        // <include>; the plugin then reads the resolved path, made absolute because plugins
        // join relative names to their own folder.
        if (const std::string* name = props.peek_string("filename"); name && !name->empty()) {
            std::filesystem::path path = resolve_file(*name, e.file().dir());
            if (outside_scene_folder(path)) throw props.error("filename", outside_message(path));
            props.replace_string("filename", std::filesystem::absolute(path).string());
        }
        return props;
    }

    // <spectrum name="n" filename="f.spd"/>: the file resolves and is confined as every file.
    void read_spectrum_file_property(const XmlElement& e, Properties& props) {
        const std::string name = e.required("filename");
        if (name.empty()) throw SceneError(e.where(), "<spectrum>: empty filename");
        const std::filesystem::path path = resolve_file(name, e.file().dir());
        if (outside_scene_folder(path))
            throw SceneError(e.where(), "<spectrum>: " + outside_message(path));
        std::error_code ec;
        if (!std::filesystem::is_regular_file(path, ec))
            throw SceneError(e.where(), "<spectrum>: file not found: " + path.string() +
                                            searched(name, e.file().dir()));
        if (std::filesystem::file_size(path, ec) > kMaxSpectrumFileBytes)
            throw SceneError(e.where(), "<spectrum>: " + path.string() + " is larger than " +
                                            std::to_string(kMaxSpectrumFileBytes) + " bytes");
        read_spectrum_file(e, read_file_bytes(path), path.string(), props);
    }

    Properties read_plain_object(const XmlElement& e, const std::string& plugin_class) {
        return read_object(e, plugin_class, [](const XmlElement&, Properties&) { return false; });
    }

    void register_id(const std::string& id, const SourceLocation& where) {
        auto [it, inserted] = ids_.emplace(id, where);
        if (!inserted)
            throw SceneError(where, "duplicate id \"" + id + "\" (first used at " +
                                        it->second.to_string() + ")");
    }

    std::shared_ptr<const Bsdf> lookup_bsdf(const XmlElement& ref) {
        ref.check_attributes({"id", "name"});
        std::string id = ref.required("id");
        auto it = bsdfs_.find(id);
        if (it == bsdfs_.end()) {
            if (ids_.count(id))
                throw SceneError(ref.where(),
                                 "<ref id=\"" + id + "\">: \"" + id + "\" is not a bsdf");
            throw SceneError(ref.where(), "<ref>: unknown id \"" + id +
                                              "\" (a bsdf must be defined before it is "
                                              "referenced)");
        }
        return it->second;
    }

    // ----- the scene element -----

    void read_scene_element(const XmlFile& file) {
        XmlElement root(file.scene(), file, params_);
        // Mitsuba resolves <ref>s after the whole file is parsed, so a shape may reference a
        // named area emitter defined further down the same file (its Cornell boxes do).
        std::vector<std::string> pending_here;
        for (const XmlElement& e : root.children())
            if (is_named_area_emitter(e) &&
                pending_area_emitters_.emplace(*e.optional("id"), e).second)
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

    void read_default(const XmlElement& e) {
        e.check_attributes({"name", "value"});
        if (!e.children().empty())
            throw SceneError(e.where(), "<default> cannot have child elements");
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

    void read_include(const XmlElement& e) {
        e.check_attributes({"filename"});
        if (!e.children().empty())
            throw SceneError(e.where(), "<include> cannot have child elements");
        std::filesystem::path file = e.required("filename");
        if (file.empty()) throw SceneError(e.where(), "<include>: empty filename");
        std::filesystem::path path = resolve_file(file, e.file().dir());
        if (outside_scene_folder(path))
            throw SceneError(e.where(), "<include>: " + outside_message(path));
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
                throw SceneError(e.where(), "<include>: include cycle: " + path.string() +
                                                " is already being read");
        include_stack_.push_back(name);
        read_scene_element(*included);
        include_stack_.pop_back();
    }

    // <path value="folder"/>: one more folder for file names to be looked up in (after the
    // naming file's folder and the main scene's folder), from here on. A relative folder is
    // relative to the main scene's folder. A folder that does not exist is ignored with a
    // warning: a job's folder holds only the files its scene uses.
    void read_path(const XmlElement& e) {
        e.check_attributes({"value"});
        if (!e.children().empty()) throw SceneError(e.where(), "<path> cannot have child elements");
        const std::string value = e.required("value");
        if (value.empty()) throw SceneError(e.where(), "<path> has an empty value");
        std::filesystem::path folder = resolver_.search_folder(value);
        if (outside_scene_folder(folder))
            throw SceneError(e.where(), "<path>: " + outside_message(folder));
        std::error_code ec;
        if (!std::filesystem::is_directory(folder, ec))
            warn(e.where(), "<path>: folder not found: " + folder.string());
        resolver_.add_search_path(folder);
    }

    void read_integrator(const XmlElement& e) {
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
    void read_integrator_object(const XmlElement& e) {
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
            if (rr_depth < 1 || rr_depth > 1000000)
                throw props.error("rr_depth", "must be positive");
            s.max_depth = int(max_depth);
            s.rr_depth = int(rr_depth);
            warn_unused();
            return 0;
        });
    }

    // ----- sensor, film, sampler -----

    void read_sensor(const XmlElement& e) {
        if (have_sensor_)
            throw SceneError(e.where(), "only one <sensor> is supported (first at " +
                                            sensor_where_.to_string() + ")");
        int width = 768, height = 576;  // Mitsuba's hdrfilm defaults
        const Medium* camera_medium = nullptr;
        bool have_film = false, have_sampler = false;
        Properties props = read_object(e, "sensor", [&](const XmlElement& c, Properties&) {
            if (c.tag() == "film") {
                if (have_film) throw SceneError(c.where(), "a sensor has only one <film>");
                read_film(c, width, height);
                have_film = true;
                return true;
            }
            if (c.tag() == "sampler") {
                if (have_sampler) throw SceneError(c.where(), "a sensor has only one <sampler>");
                read_sampler(c);
                have_sampler = true;
                return true;
            }
            // The medium the camera sits in (fog around the camera).
            if (c.tag() == "medium" || c.tag() == "ref") {
                if (camera_medium) throw SceneError(c.where(), "a sensor has only one medium");
                if (c.tag() == "ref") c.check_attributes({"id", "name"});
                camera_medium = c.tag() == "medium" ? read_medium_object(c) : lookup_medium(c);
                return true;
            }
            return false;
        });
        if (props.type() != "perspective")
            throw SceneError(
                e.where(), "unknown sensor type \"" + props.type() + "\" (supported: perspective)");
        PerspectiveCamera camera = build(props, [&] {
            float fov = 0;
            char fov_axis = 'x';
            if (props.has("fov") && props.has("focal_length"))
                throw props.error("focal_length", "give either \"fov\" or \"focal_length\"");
            if (props.has("fov")) {
                fov = props.get_float("fov");
                if (!(fov > 0 && fov < 180))
                    throw props.error("fov", "must be in (0, 180) degrees");
                std::string axis = props.get_string("fov_axis", "x");
                if (axis == "x")
                    fov_axis = 'x';
                else if (axis == "y")
                    fov_axis = 'y';
                else if (axis == "diagonal")
                    fov_axis = 'd';
                else if (axis == "smaller")
                    fov_axis = width <= height ? 'x' : 'y';
                else if (axis == "larger")
                    fov_axis = width >= height ? 'x' : 'y';
                else
                    throw props.error("fov_axis", "\"" + axis +
                                                      "\" is not supported (x, y, diagonal, "
                                                      "smaller or larger)");
            } else {
                // Mitsuba: a lens of this focal length on a 36 x 24 mm film; its diagonal
                // field of view becomes the image's diagonal (fov_axis does not apply).
                fov = fov_from_focal_length(props);
                fov_axis = 'd';
            }
            float near_clip = props.get_float("near_clip", 0.01f);
            float far_clip = props.get_float("far_clip", 10000.0f);
            if (!(near_clip > 0)) throw props.error("near_clip", "must be positive");
            if (!(far_clip > near_clip))
                throw props.error("far_clip", "must be larger than near_clip");
            // Mitsuba's projective cameras all read `focus_distance`; a pinhole has no focus,
            // so the value has no effect there (as in Mitsuba), but it must be a number.
            props.get_float("focus_distance", far_clip);
            // A shifted principal point (off-axis projection) is not implemented; the zero
            // offsets exporters write are the identity.
            for (const char* name : {"principal_point_offset_x", "principal_point_offset_y"})
                if (props.get_float(name, 0.0f) != 0.0f)
                    throw props.error(name,
                                      "a non-zero principal point offset is not supported yet");
            Transform to_world = props.get_transform("to_world", Transform());
            if (to_world.is_singular()) throw props.error("to_world", "the transform is singular");
            PerspectiveCamera camera(to_world, fov, fov_axis, width, height);
            if (!within_scene_limits(camera.position()))
                throw props.error("to_world", "places the camera beyond 1e12 from the origin");
            return camera;
        });
        scene_.set_camera(camera);
        scene_.set_camera_medium(camera_medium);
        have_sensor_ = true;
        sensor_where_ = e.where();
    }

    // `focal_length` ("50mm" as Mitsuba writes it, or a number of millimetres; default 50 mm)
    // as the diagonal field of view of a 36 x 24 mm film, in degrees.
    static float fov_from_focal_length(const Properties& props) {
        float mm = 50.0f;
        if (const std::string* text = props.peek_string("focal_length")) {
            std::string number = props.get_string("focal_length");
            if (number.size() > 2 && number.compare(number.size() - 2, 2, "mm") == 0)
                number.resize(number.size() - 2);
            try {
                size_t used = 0;
                mm = std::stof(number, &used);
                if (used != number.size()) mm = -1;
            } catch (const std::exception&) {
                mm = -1;
            }
            if (!(mm > 0) || !std::isfinite(mm))
                throw props.error("focal_length", "\"" + *text +
                                                      "\" is not a positive length such as "
                                                      "\"50mm\"");
        } else if (props.has("focal_length")) {
            mm = props.get_float("focal_length");
            if (!(mm > 0) || !std::isfinite(mm))
                throw props.error("focal_length", "must be a positive length in millimetres");
        }
        const double diagonal_mm = std::sqrt(36.0 * 36.0 + 24.0 * 24.0);
        return float(2.0 * std::atan(diagonal_mm / (2.0 * double(mm))) * 180.0 / 3.14159265358979);
    }

    void read_film(const XmlElement& e, int& width, int& height) {
        Properties props = read_object(e, "film", [&](const XmlElement& c, Properties&) {
            if (c.tag() != "rfilter") return false;
            read_rfilter(c);
            return true;
        });
        if (props.type() != "hdrfilm")
            throw SceneError(e.where(),
                             "unknown film type \"" + props.type() + "\" (supported: hdrfilm)");
        build(props, [&] {
            int64_t w = props.get_int("width", 768), h = props.get_int("height", 576);
            if (w < 1 || w > 65536) throw props.error("width", "must be in [1, 65536]");
            if (h < 1 || h > 65536) throw props.error("height", "must be in [1, 65536]");
            // Accepted for compatibility; the renderer always writes float RGB OpenEXR.
            props.get_string("file_format", "openexr");
            props.get_string("pixel_format", "rgb");
            props.get_string("component_format", "float32");
            width = int(w), height = int(h);
            return 0;
        });
    }

    void read_rfilter(const XmlElement& e) {
        Properties props = read_plain_object(e, "rfilter");
        // Every value is read (validated) but ignored.
        if (props.type() != "box" && !warned_rfilter_) {
            std::cerr << "warning: " << e.where().to_string()
                      << ": reconstruction filters are ignored (a box filter is used)\n";
            warned_rfilter_ = true;
        }
    }

    void read_sampler(const XmlElement& e) {
        Properties props = read_plain_object(e, "sampler");
        bool known = false;
        for (const char* t : kSamplerTypes) known = known || props.type() == t;
        if (!known)
            throw SceneError(e.where(), "unknown sampler type \"" + props.type() +
                                            "\" (supported: independent; stratified, "
                                            "multijitter, orthogonal, ldsampler, halton and sobol "
                                            "are accepted and rendered as independent)");
        build(props, [&] {
            int64_t n = props.get_int("sample_count", scene_.settings.sample_count);
            if (n < 1 || n > (int64_t(1) << 31) - 1)
                throw props.error("sample_count", "must be a positive integer");
            props.get_int("seed", 0);  // accepted; the job's seed is used
            scene_.settings.sample_count = int(n);
            return 0;
        });
    }

    // ----- BSDFs -----

    std::shared_ptr<const Bsdf> read_bsdf_object(const XmlElement& e) {
        Properties props = read_object(e, "bsdf", [&](const XmlElement& c, Properties& p) {
            if (c.tag() == "bsdf") {
                p.nested_bsdfs.push_back(read_bsdf_object(c));
                return true;
            }
            if (read_texture_child(c, p)) return true;
            if (c.tag() == "ref") {
                if (!c.children().empty())
                    throw SceneError(c.where(), "<ref> cannot have child elements");
                p.nested_bsdfs.push_back(lookup_bsdf(c));
                return true;
            }
            return false;
        });
        refuse_nested_normal_maps(props);
        std::shared_ptr<const Bsdf> bsdf = build(props, [&] { return make_bsdf(props); });
        if (!bsdf) throw SceneError(e.where(), "bsdf \"" + props.type() + "\" was not built");
        if (!props.id.empty()) {
            register_id(props.id, e.where());
            bsdfs_[props.id] = bsdf;
        }
        return bsdf;
    }

    void read_bsdf(const XmlElement& e) { keep(read_bsdf_object(e)); }

    // A wrapper resolves its children at a hit without their shading frame, so a normal or bump
    // map must be the outermost bsdf (Mitsuba's examples write it so: normalmap around
    // twosided).
    static void refuse_nested_normal_maps(const Properties& props) {
        if (props.type() == "normalmap" || props.type() == "bumpmap")
            return;  // they refuse a nested one themselves
        for (const auto& nested : props.nested_bsdfs)
            if (nested->changes_shading_frame())
                throw SceneError(props.where(), "bsdf \"" + props.type() +
                                                    "\" cannot wrap a normalmap or bumpmap: "
                                                    "write the map around it instead");
    }

    // ----- textures -----

    // <texture type="..."> at the top level (with an id, for <ref>) or nested in a plugin
    // (with the name of the parameter it gives). Textures nest: checkerboard's colours.
    std::shared_ptr<const Texture> read_texture_object(const XmlElement& e) {
        Properties props = read_object(e, "texture", [&](const XmlElement& c, Properties& p) {
            return read_texture_child(c, p);
        });
        std::shared_ptr<const Texture> texture = build(props, [&] { return make_texture(props); });
        if (!props.id.empty()) {
            register_id(props.id, e.where());
            textures_[props.id] = texture;
        }
        return texture;
    }

    // A plugin's child that gives a texture parameter: a nested <texture name="..."> or a
    // <ref name="..." id="..."/> to a texture. False for any other child (a <ref> to something
    // else included), which the plugin's reader then handles.
    bool read_texture_child(const XmlElement& c, Properties& p) {
        if (c.tag() == "texture") {
            const std::optional<std::string> name = c.optional("name");
            if (!name || name->empty())
                throw SceneError(c.where(), "a <texture> inside " + p.plugin_class() + " \"" +
                                                p.type() +
                                                "\" needs name=\"parameter\" (e.g. "
                                                "name=\"reflectance\")");
            p.set(*name, read_texture_object(c), c.where());
            return true;
        }
        if (c.tag() != "ref") return false;
        const std::optional<std::string> id = c.optional("id");
        if (!id) return false;
        auto it = textures_.find(*id);
        if (it == textures_.end()) return false;
        c.check_attributes({"id", "name"});
        if (!c.children().empty()) throw SceneError(c.where(), "<ref> cannot have child elements");
        const std::optional<std::string> name = c.optional("name");
        if (!name || name->empty())
            throw SceneError(c.where(), "<ref id=\"" + *id +
                                            "\">: a texture reference needs name=\"parameter\" "
                                            "(e.g. name=\"reflectance\")");
        p.set(*name, it->second, c.where());
        return true;
    }

    // Hands a BSDF to the scene once, however many shapes use it.
    const Bsdf* keep(std::shared_ptr<const Bsdf> bsdf) {
        if (kept_.insert(bsdf.get()).second) scene_.add_bsdf(bsdf);
        return bsdf.get();
    }

    const Bsdf* default_bsdf(const SourceLocation& where) {
        if (!default_bsdf_) {
            // A shape without a BSDF gets Mitsuba 3's default: diffuse with reflectance 0.5.
            Properties props("bsdf", "diffuse", where);
            default_bsdf_ = keep(build(props, [&] { return make_bsdf(props); }));
        }
        return default_bsdf_;
    }

    // ----- media -----

    std::shared_ptr<const PhaseFunction> read_phase(const XmlElement& e) {
        Properties props = read_plain_object(e, "phase");
        return build(props, [&] { return make_phase(props); });
    }

    std::shared_ptr<const Volume> read_volume(const XmlElement& e) {
        Properties props = read_plain_object(e, "volume");
        return build(props, [&] { return make_volume(props, e.file().dir().string()); });
    }

    // <medium type="..."> with an optional nested <phase> and nested <volume name="...">.
    const Medium* read_medium_object(const XmlElement& e) {
        std::shared_ptr<const PhaseFunction> phase;
        std::map<std::string, std::shared_ptr<const Volume>> volumes;
        Properties props = read_object(e, "medium", [&](const XmlElement& c, Properties&) {
            if (c.tag() == "phase") {
                if (phase) throw SceneError(c.where(), "a medium has at most one <phase>");
                phase = read_phase(c);
                return true;
            }
            if (c.tag() == "volume") {
                const std::string name = c.required("name");
                if (volumes.count(name))
                    throw SceneError(c.where(), "volume \"" + name + "\" is given twice");
                volumes[name] = read_volume(c);
                return true;
            }
            return false;
        });
        std::shared_ptr<const Medium> medium =
            build(props, [&] { return make_medium(props, phase, volumes); });
        if (!medium) throw SceneError(e.where(), "medium \"" + props.type() + "\" was not built");
        if (!props.id.empty()) {
            register_id(props.id, e.where());
            media_[props.id] = medium.get();
        }
        const std::string name = (props.id.empty() ? "medium" : "medium \"" + props.id + "\"") +
                                 " (" + e.where().to_string() + ")";
        return scene_.add_medium(std::move(medium), name);
    }

    const Medium* lookup_medium(const XmlElement& ref) {
        const std::string id = ref.required("id");
        auto it = media_.find(id);
        if (it == media_.end()) {
            if (ids_.count(id))
                throw SceneError(ref.where(),
                                 "<ref id=\"" + id + "\">: \"" + id + "\" is not a medium");
            throw SceneError(ref.where(), "<ref>: unknown medium \"" + id +
                                              "\" (a medium must be defined before it is "
                                              "referenced)");
        }
        return it->second;
    }

    const Bsdf* null_bsdf(const SourceLocation& where) {
        if (!null_bsdf_) {
            Properties props("bsdf", "null", where);
            null_bsdf_ = keep(build(props, [&] { return make_bsdf(props); }));
        }
        return null_bsdf_;
    }

    // ----- emitters and shapes -----

    static bool is_named_area_emitter(const XmlElement& e) {
        return e.tag() == "emitter" && e.optional("type") == "area" && e.has("id");
    }

    // `<emitter type="area" id="X">` outside a shape defines an emitter that shapes attach
    // with `<ref id="X"/>`; each referencing shape builds its own light from these values.
    const Properties& read_named_area_emitter(const XmlElement& e) {
        Properties props = read_object(e, "emitter", [&](const XmlElement& t, Properties& p) {
            return read_texture_child(t, p);
        });
        register_id(props.id, e.where());
        return area_emitters_.emplace(props.id, std::move(props)).first->second;
    }

    // The named area emitter `id`, read now if it is defined later in an open file.
    const Properties* find_area_emitter(const std::string& id) {
        if (auto it = area_emitters_.find(id); it != area_emitters_.end()) return &it->second;
        if (auto it = pending_area_emitters_.find(id); it != pending_area_emitters_.end()) {
            read_ahead_.insert(id);
            return &read_named_area_emitter(it->second);
        }
        return nullptr;
    }

    void read_top_level_emitter(const XmlElement& e) {
        if (is_named_area_emitter(e)) {
            // Already read when a shape referenced it before its definition.
            if (!read_ahead_.erase(*e.optional("id"))) read_named_area_emitter(e);
            return;
        }
        // A nested medium (or a reference to one) is the medium the light sits in.
        const Medium* medium = nullptr;
        Properties props = read_object(e, "emitter", [&](const XmlElement& c, Properties& p) {
            if (read_texture_child(c, p)) return true;
            if (c.tag() != "medium" && c.tag() != "ref") return false;
            if (medium) throw SceneError(c.where(), "an emitter sits in one medium only");
            if (c.tag() == "ref") c.check_attributes({"id", "name"});
            medium = c.tag() == "medium" ? read_medium_object(c) : lookup_medium(c);
            return true;
        });
        if (props.type() == "area")
            throw SceneError(e.where(), "an area emitter must be nested in a <shape>");
        std::unique_ptr<Light> light =
            build(props, [&] { return make_light(props, nullptr, e.file().dir()); });
        if (!light) throw SceneError(e.where(), "emitter \"" + props.type() + "\" was not built");
        if (!props.id.empty()) register_id(props.id, e.where());
        light->medium = medium;
        scene_.add_light(std::move(light));
    }

    void read_shape(const XmlElement& e) {
        if (const std::optional<std::string> type = e.optional("type")) {
            if (*type == "shapegroup") return read_shapegroup(e);
            if (*type == "instance") return read_instance(e);
        }
        const Medium* interior = nullptr;
        const Medium* exterior = nullptr;
        bool has_interface = false;
        // `<ref name="interior|exterior" id="..."/>` or a nested `<medium name="...">`.
        auto set_medium = [&](const XmlElement& c, const Medium* medium) {
            const std::string name = c.required("name");
            const Medium*& slot = name == "interior" ? interior : exterior;
            if (slot || (name != "interior" && name != "exterior"))
                throw SceneError(c.where(), name == "interior" || name == "exterior"
                                                ? "the shape's " + name + " medium is given twice"
                                                : "a medium inside a <shape> needs name="
                                                  "\"interior\" or name=\"exterior\"");
            slot = medium;
            has_interface = true;
        };
        std::shared_ptr<const Bsdf> bsdf;
        SourceLocation bsdf_where;
        std::optional<Properties> emitter;
        auto set_bsdf = [&](std::shared_ptr<const Bsdf> b, const XmlElement& c) {
            if (bsdf)
                throw SceneError(c.where(), "a shape has at most one bsdf (first at " +
                                                bsdf_where.to_string() + ")");
            bsdf = std::move(b);
            bsdf_where = c.where();
        };
        Properties props = read_object(e, "shape", [&](const XmlElement& c, Properties&) {
            if (c.tag() == "bsdf") {
                set_bsdf(read_bsdf_object(c), c);
                return true;
            }
            if (c.tag() == "ref") {
                if (!c.children().empty())
                    throw SceneError(c.where(), "<ref> cannot have child elements");
                c.check_attributes({"id", "name"});
                std::optional<std::string> name = c.optional("name");
                if (name && (*name == "interior" || *name == "exterior")) {
                    set_medium(c, lookup_medium(c));
                } else if (const Properties* named = find_area_emitter(c.required("id"))) {
                    if (emitter) throw SceneError(c.where(), "a shape has at most one emitter");
                    emitter = *named;
                } else {
                    set_bsdf(lookup_bsdf(c), c);
                }
                return true;
            }
            if (c.tag() == "medium") {
                set_medium(c, read_medium_object(c));
                return true;
            }
            if (c.tag() == "emitter") {
                if (emitter) throw SceneError(c.where(), "a shape has at most one emitter");
                // The area light's radiance may be a texture.
                emitter = read_object(c, "emitter", [&](const XmlElement& t, Properties& p) {
                    return read_texture_child(t, p);
                });
                if (emitter->type() != "area")
                    throw SceneError(c.where(),
                                     "an emitter inside a <shape> must be of type "
                                     "\"area\", not \"" +
                                         emitter->type() + "\"");
                return true;
            }
            return false;
        });
        if (!props.id.empty()) register_id(props.id, e.where());
        if (open_group_ && emitter)
            throw SceneError(emitter->where(),
                             "an emitter inside a shapegroup is not supported (instances cannot "
                             "emit, as in Mitsuba)");
        std::unique_ptr<Shape> shape =
            build(props, [&] { return make_shape(props, e.file().dir()); });
        check_shape_extent(*shape, e);
        std::unique_ptr<Light> light;
        if (emitter) {
            light =
                build(*emitter, [&] { return make_light(*emitter, shape.get(), e.file().dir()); });
            if (!light) throw SceneError(emitter->where(), "the area emitter was not built");
            shape->emitter = light.get();
            light->medium = exterior;  // an area light emits on its normal's side
        }
        shape->interior = interior;
        shape->exterior = exterior;
        // A shape that only bounds media (no BSDF) is an index-matched boundary.
        const Bsdf* b = bsdf            ? keep(bsdf)
                        : has_interface ? null_bsdf(e.where())
                                        : default_bsdf(e.where());
        if (open_group_) return open_group_->add(std::move(shape), b);
        scene_.add_shape(std::move(shape), b);
        if (light) scene_.add_light(std::move(light));
    }

    // <shape type="shapegroup" id="..."> with <shape> children: defined once, placed by
    // instances (core/shapes/instance.h). Its shapes are in the group's own space.
    void read_shapegroup(const XmlElement& e) {
        if (open_group_)
            throw SceneError(e.where(), "a shapegroup cannot be nested in another shapegroup");
        e.check_attributes({"type", "id", "name"});
        const std::optional<std::string> id = e.optional("id");
        if (!id || id->empty())
            throw SceneError(e.where(), "a shapegroup needs an id (instances refer to it)");
        // (A failed load discards the loader, so open_group_ needs no reset on errors.)
        auto group = std::make_shared<ShapeGroup>(*id);
        open_group_ = group.get();
        for (const XmlElement& c : e.children()) {
            if (c.tag() != "shape") {
                if (is_property_tag(c.tag()))
                    throw SceneError(c.where(), "shapegroup \"" + *id +
                                                    "\": a shapegroup takes no parameters (only "
                                                    "<shape> children)");
                unknown_tag(c, e.describe());
            }
            const std::optional<std::string> type = c.optional("type");
            if (type && (*type == "shapegroup" || *type == "instance"))
                throw SceneError(c.where(), "a " + *type +
                                                " inside a shapegroup is not supported (nested "
                                                "instancing)");
            read_shape(c);
        }
        open_group_ = nullptr;
        if (group->empty()) throw SceneError(e.where(), "shapegroup \"" + *id + "\" has no shapes");
        register_id(*id, e.where());
        groups_[*id] = std::move(group);
    }

    // <shape type="instance"> with a <ref id="group"/> and an optional to_world.
    void read_instance(const XmlElement& e) {
        std::shared_ptr<const ShapeGroup> group;
        Properties props = read_object(e, "shape", [&](const XmlElement& c, Properties&) {
            if (c.tag() != "ref") return false;
            c.check_attributes({"id", "name"});
            if (!c.children().empty())
                throw SceneError(c.where(), "<ref> cannot have child elements");
            if (group) throw SceneError(c.where(), "an instance refers to one shapegroup");
            const std::string id = c.required("id");
            auto it = groups_.find(id);
            if (it == groups_.end())
                throw SceneError(c.where(), ids_.count(id)
                                                ? "<ref id=\"" + id + "\">: \"" + id +
                                                      "\" is not a shapegroup (an instance "
                                                      "takes no bsdf, emitter or medium)"
                                                : "<ref>: unknown shapegroup \"" + id +
                                                      "\" (it must be defined before its "
                                                      "instances)");
            group = it->second;
            return true;
        });
        if (!group)
            throw SceneError(e.where(), "an instance needs <ref id=\"...\"/> to a shapegroup");
        if (!props.id.empty()) register_id(props.id, e.where());
        std::unique_ptr<Instance> instance = build(props, [&] {
            const Transform to_world = props.get_transform("to_world", Transform());
            if (to_world.is_singular()) throw props.error("to_world", "the transform is singular");
            return std::make_unique<Instance>(
                group, to_world,
                props.id.empty() ? "instance (" + e.where().to_string() + ")" : props.id);
        });
        if (!within_scene_limits(*instance))
            throw SceneError(e.where(), e.describe() +
                                            ": its geometry reaches beyond 1e12 from the origin "
                                            "or is not finite (check its to_world transform)");
        scene_.add_instance(std::move(instance));
    }

    // Refuses geometry beyond the scene's limits (within_scene_limits, core/scene/scene.h).
    static void check_shape_extent(const Shape& shape, const XmlElement& e) {
        if (!within_scene_limits(shape))
            throw SceneError(e.where(), e.describe() +
                                            ": its geometry reaches beyond 1e12 from the origin "
                                            "or is not finite (check its to_world transform)");
    }

    Scene& scene_;
    ParameterTable params_;
    FileResolver resolver_;
    bool confined_ = false;
    std::filesystem::path confine_root_;
    std::vector<std::string> include_stack_;
    std::map<std::string, std::shared_ptr<const Bsdf>> bsdfs_;
    std::map<std::string, std::shared_ptr<const Texture>> textures_;
    std::map<std::string, SourceLocation> ids_;
    // Named area emitters: read ones, and those of the files being read not read yet.
    std::map<std::string, Properties> area_emitters_;
    std::map<std::string, XmlElement> pending_area_emitters_;
    std::set<std::string> read_ahead_;  // read before their position in the file
    std::set<const Bsdf*> kept_;
    const Bsdf* default_bsdf_ = nullptr;
    const Bsdf* null_bsdf_ = nullptr;
    std::map<std::string, const Medium*> media_;
    std::map<std::string, std::shared_ptr<const ShapeGroup>> groups_;
    ShapeGroup* open_group_ = nullptr;  // the shapegroup whose shapes are being read
    bool have_sensor_ = false, have_integrator_ = false, warned_rfilter_ = false;
    SourceLocation sensor_where_, integrator_where_;
};

std::unique_ptr<Scene> load(const XmlFile& file, const std::map<std::string, std::string>& defines,
                            const std::string& source_file,
                            const std::filesystem::path& confine_to) {
    auto scene = std::make_unique<Scene>();
    scene->source_file = source_file;
    try {
        Loader(*scene, defines, confine_to).load_root(file);
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
