#pragma once

// The Mitsuba XML loader behind load_scene (scene_loader.h): one Loader per load, its member
// functions implemented by element family, as the pbrt loader is split:
//
//   scene_loader.cpp  the core: walks <scene> (and included files), dispatches each element,
//                     <default>, <include>, <path>, <integrator>, file resolution and the
//                     helpers every family uses (read_object, build, ids)
//   sensor.cpp        <sensor>, <film>, <rfilter>, <sampler>
//   bsdfs.cpp         <bsdf> and references to one, the default and null BSDFs
//   textures.cpp      <texture>, top-level and nested as a plugin's parameter
//   media.cpp         <medium>, <phase>, <volume> and references to a medium
//   emitters.cpp      top-level <emitter>s and named area emitters
//   shapes.cpp        <shape> with its bsdf, area emitter and media
//   instancing.cpp    shapegroups and instances
//
// The accepted tags, plugins and parameters are documented in docs/reference/scene-format.md; keep
// the two in step.

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/media/medium.h"
#include "core/media/phase_function.h"
#include "core/media/volume.h"
#include "core/scene/loader/file_resolver.h"
#include "core/scene/loader/property_reader.h"
#include "core/scene/loader/values.h"
#include "core/scene/loader/xml_element.h"
#include "core/scene/loader/xml_file.h"
#include "core/scene/scene.h"
#include "core/shapes/instance.h"
#include "core/textures/texture.h"

namespace render::mitsuba {

class Loader {
  public:
    Loader(Scene& scene, const std::map<std::string, std::string>& defines,
           const std::filesystem::path& confine_to)
        : scene_(scene),
          params_(defines.begin(), defines.end()),
          resolver_("."),
          confinement_(confine_to) {}

    void load_root(const XmlFile& file);

  private:
    // ----- generic helpers (scene_loader.cpp) -----

    static std::string canonical_name(const XmlFile& file);
    static void warn(const SourceLocation& where, const std::string& message);
    std::filesystem::path resolve_file(const std::filesystem::path& name,
                                       const std::filesystem::path& naming_dir) const;
    std::string searched(const std::filesystem::path& name,
                         const std::filesystem::path& naming_dir) const;
    [[noreturn]] static void unknown_tag(const XmlElement& e, const std::string& context);

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
        resolve_filename(e, props);
        return props;
    }

    void resolve_filename(const XmlElement& e, Properties& props) const;
    void read_spectrum_file_property(const XmlElement& e, Properties& props);
    Properties read_plain_object(const XmlElement& e, const std::string& plugin_class);
    void register_id(const std::string& id, const SourceLocation& where);

    // ----- the scene element (scene_loader.cpp) -----

    void read_scene_element(const XmlFile& file);
    void read_default(const XmlElement& e);
    void read_include(const XmlElement& e);
    void read_path(const XmlElement& e);
    void read_integrator(const XmlElement& e);
    void read_integrator_object(const XmlElement& e);

    // ----- sensor, film, sampler (sensor.cpp) -----

    void read_sensor(const XmlElement& e);
    static float fov_from_focal_length(const Properties& props);
    void read_film(const XmlElement& e, int& width, int& height);
    void read_rfilter(const XmlElement& e);
    void read_sampler(const XmlElement& e);

    // ----- BSDFs (bsdfs.cpp) -----

    std::shared_ptr<const Bsdf> read_bsdf_object(const XmlElement& e);
    void read_bsdf(const XmlElement& e);
    static void refuse_nested_normal_maps(const Properties& props);
    std::shared_ptr<const Bsdf> lookup_bsdf(const XmlElement& ref);
    const Bsdf* keep(std::shared_ptr<const Bsdf> bsdf);
    const Bsdf* default_bsdf(const SourceLocation& where);
    const Bsdf* null_bsdf(const SourceLocation& where);

    // ----- textures (textures.cpp) -----

    std::shared_ptr<const Texture> read_texture_object(const XmlElement& e);
    bool read_texture_child(const XmlElement& c, Properties& p);

    // ----- media (media.cpp) -----

    std::shared_ptr<const PhaseFunction> read_phase(const XmlElement& e);
    std::shared_ptr<const Volume> read_volume(const XmlElement& e);
    const Medium* read_medium_object(const XmlElement& e);
    const Medium* lookup_medium(const XmlElement& ref);

    // ----- emitters (emitters.cpp) -----

    static bool is_named_area_emitter(const XmlElement& e);
    const Properties& read_named_area_emitter(const XmlElement& e);
    const Properties* find_area_emitter(const std::string& id);
    void read_top_level_emitter(const XmlElement& e);

    // ----- shapes (shapes.cpp) and instancing (instancing.cpp) -----

    void read_shape(const XmlElement& e);
    static void check_shape_extent(const Shape& shape, const XmlElement& e);
    void read_shapegroup(const XmlElement& e);
    void read_instance(const XmlElement& e);

    Scene& scene_;
    ParameterTable params_;
    FileResolver resolver_;
    FolderConfinement confinement_;
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

}  // namespace render::mitsuba
