// pbrt-v4 directives: the options block (Camera, Film, Sampler, Integrator, ...), WorldBegin,
// the world block (shapes, materials, lights, textures), transforms, attributes and includes.
// Each directive is checked here; its plugin is built in materials.cpp, shapes.cpp, lights.cpp
// or textures.cpp. docs/reference/scene-format.md, "pbrt-v4 scenes", lists everything accepted.

#include "core/scene/pbrt/scene_loader.h"

#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/base/memory_budget.h"
#include "core/base/ray_transform_check.h"
#include "core/scene/loader/file_resolver.h"
#include "core/scene/pbrt/builders.h"
#include "core/scene/pbrt/graphics_state.h"
#include "core/scene/pbrt/tokenizer.h"
#include "core/scene/pbrt/transforms.h"
#include "core/shapes/alpha_cutout.h"
#include "core/shapes/instance.h"

namespace render::pbrt {
namespace {

namespace fs = std::filesystem;

constexpr int kMaxIncludeDepth = 32;

std::string read_text(const fs::path& path, const SourceLocation& from) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) throw SceneError(from, "file not found: " + path.string());
    charge_file_contents(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw SceneError(from, "cannot read " + path.string());
    std::ostringstream out;
    out << in.rdbuf();
    return out.str();
}

class Loader {
  public:
    Loader(Scene& scene, fs::path scene_dir, const fs::path& confine_to)
        : scene_(scene), scene_dir_(std::move(scene_dir)), confinement_(confine_to) {}

    void run_file(const fs::path& path, const SourceLocation& from, int depth) {
        if (depth > kMaxIncludeDepth) throw SceneError(from, "includes are nested too deeply");
        const std::string key = canonical_path(path).string();
        if (open_files_.count(key))
            throw SceneError(from, "include cycle: " + path.string() + " is already being read");
        Tokenizer tokens(read_text(path, from), path.string());
        open_files_.insert(key);
        parse(tokens, depth);
        open_files_.erase(key);
    }

    void run_text(const std::string& text, const std::string& name) {
        Tokenizer tokens(text, name);
        parse(tokens, 0);
    }

    void finish(const std::string& file) {
        if (!world_) throw SceneError(SourceLocation{file, 0}, "the file has no WorldBegin");
        if (object_) throw SceneError(object_where_, "ObjectBegin without ObjectEnd");
        if (!attributes_.empty())
            throw SceneError(attributes_.back().second, "AttributeBegin without AttributeEnd");
    }

  private:
    // ----- helpers -----

    // pbrt resolves relative names against the main scene file's folder.
    fs::path resolve(const std::string& name, const SourceLocation& where) const {
        if (name.empty()) throw SceneError(where, "empty file name");
        fs::path p(name);
        if (p.is_relative()) p = scene_dir_ / p;
        p = p.lexically_normal();
        if (confinement_.outside(p)) throw SceneError(where, confinement_.outside_message(p));
        return p;
    }

    std::function<fs::path(const ParamList&, const std::string&)> resolver() const {
        return [this](const ParamList& params, const std::string& name) {
            return resolve(params.get_string(name, ""), params.find(name)->where);
        };
    }

    static Token need_token(Tokenizer& tokens, const Token& directive, const char* what) {
        std::optional<Token> t = tokens.next();
        if (!t) throw SceneError(directive.where, directive.text + ": missing " + what);
        return *t;
    }

    static std::string need_string(Tokenizer& tokens, const Token& directive, const char* what) {
        Token t = need_token(tokens, directive, what);
        if (!t.quoted)
            throw SceneError(t.where, directive.text + ": expected a quoted " + std::string(what) +
                                          ", got " + t.text);
        return t.text;
    }

    template <size_t N>
    static std::array<double, N> numbers(Tokenizer& tokens, const Token& directive,
                                         bool bracketed) {
        std::array<double, N> out{};
        if (bracketed) {
            Token open = need_token(tokens, directive, "[");
            if (!open.is("["))
                throw SceneError(open.where, directive.text + ": expected [, got " + open.text);
        }
        for (size_t i = 0; i < N; ++i) {
            Token t = need_token(tokens, directive, "number");
            if (t.is("]") || t.is("["))
                throw SceneError(t.where, directive.text + ": expected " + std::to_string(N) +
                                              " numbers, got " + std::to_string(i));
            out[i] = parse_number(t, directive.text);
        }
        if (bracketed) {
            Token close = need_token(tokens, directive, "]");
            if (!close.is("]"))
                throw SceneError(close.where, directive.text + ": expected ] after " +
                                                  std::to_string(N) + " numbers, got " +
                                                  close.text);
        }
        return out;
    }

    void apply(const Transform& t, const Token& directive) {
        Transform ctm = state_.ctm * t;
        for (const auto& row : ctm.matrix())
            for (double v : row)
                if (!std::isfinite(v))
                    throw SceneError(directive.where,
                                     directive.text + ": the transform is not finite");
        state_.ctm = ctm;
    }

    void need_world(const Token& d) const {
        if (!world_) throw SceneError(d.where, d.text + " is only allowed after WorldBegin");
    }
    void need_options(const Token& d) const {
        if (world_) throw SceneError(d.where, d.text + " is only allowed before WorldBegin");
    }

    static void warn_ignored(const ParamList& params, const std::string& why) {
        warn(params.where, params.context() + " is ignored (" + why + ")");
    }

    // Hands a BSDF to the scene once, however many shapes use it.
    const Bsdf* keep(const std::shared_ptr<const Bsdf>& bsdf) {
        if (kept_.insert(bsdf.get()).second) scene_.add_bsdf(bsdf);
        return bsdf.get();
    }

    // ----- the directive loop -----

    void parse(Tokenizer& tokens, int depth) {
        while (std::optional<Token> t = tokens.next()) {
            const Token& d = *t;
            if (d.quoted || d.is("[") || d.is("]"))
                throw SceneError(d.where, "expected a directive, got " +
                                              (d.quoted ? "\"" + d.text + "\"" : d.text));
            const std::string& n = d.text;
            if (n == "Include" || n == "Import") {
                const std::string file = need_string(tokens, d, "file name");
                run_file(resolve(file, d.where), d.where, depth + 1);
            } else if (n == "Identity") {
                state_.ctm = Transform();
            } else if (n == "Translate") {
                auto v = numbers<3>(tokens, d, false);
                apply(Transform::translate(Vec3(float(v[0]), float(v[1]), float(v[2]))), d);
            } else if (n == "Scale") {
                auto v = numbers<3>(tokens, d, false);
                apply(Transform::scale(Vec3(float(v[0]), float(v[1]), float(v[2]))), d);
            } else if (n == "Rotate") {
                auto v = numbers<4>(tokens, d, false);
                if (v[1] == 0 && v[2] == 0 && v[3] == 0)
                    throw SceneError(d.where, "Rotate: the axis is zero");
                apply(rotate(v[0], Vec3(float(v[1]), float(v[2]), float(v[3]))), d);
            } else if (n == "LookAt") {
                auto v = numbers<9>(tokens, d, false);
                Transform t = look_at(Vec3(float(v[0]), float(v[1]), float(v[2])),
                                      Vec3(float(v[3]), float(v[4]), float(v[5])),
                                      Vec3(float(v[6]), float(v[7]), float(v[8])));
                if (t.is_singular())
                    throw SceneError(d.where,
                                     "LookAt: the eye equals the target or up is "
                                     "parallel to the view direction");
                apply(t, d);
            } else if (n == "Transform") {
                state_.ctm = Transform();
                apply(matrix_from_pbrt(numbers<16>(tokens, d, true)), d);
            } else if (n == "ConcatTransform") {
                apply(matrix_from_pbrt(numbers<16>(tokens, d, true)), d);
            } else if (n == "CoordinateSystem") {
                coordinate_systems_[need_string(tokens, d, "name")] = state_.ctm;
            } else if (n == "CoordSysTransform") {
                const std::string name = need_string(tokens, d, "name");
                auto it = coordinate_systems_.find(name);
                if (it == coordinate_systems_.end())
                    throw SceneError(
                        d.where, "CoordSysTransform: unknown coordinate system \"" + name + "\"");
                state_.ctm = it->second;
            } else if (n == "TransformBegin") {
                transforms_.push_back(state_.ctm);
            } else if (n == "TransformEnd") {
                if (transforms_.empty())
                    throw SceneError(d.where, "TransformEnd without TransformBegin");
                state_.ctm = transforms_.back();
                transforms_.pop_back();
            } else if (n == "ActiveTransform") {
                Token which = need_token(tokens, d, "All, StartTime or EndTime");
                if (which.text != "All")
                    throw SceneError(which.where, "ActiveTransform " + which.text +
                                                      ": animated transforms are not supported");
            } else if (n == "TransformTimes") {
                numbers<2>(tokens, d, false);
                warn(d.where, "TransformTimes is ignored (no motion blur)");
            } else if (n == "AttributeBegin") {
                attributes_.emplace_back(state_, d.where);
            } else if (n == "AttributeEnd") {
                if (attributes_.empty())
                    throw SceneError(d.where, "AttributeEnd without AttributeBegin");
                state_ = attributes_.back().first;
                attributes_.pop_back();
            } else if (n == "ReverseOrientation") {
                state_.reverse_orientation = !state_.reverse_orientation;
            } else if (n == "Option") {
                ParamList p = ParamList::parse(tokens, "Option");
                p.where = d.where;
                warn_ignored(p, "rendering options are the renderer's");
            } else if (n == "ColorSpace") {
                const std::string cs = need_string(tokens, d, "colour space");
                if (cs != "srgb")
                    throw SceneError(d.where,
                                     "ColorSpace \"" + cs + "\" is not supported (only srgb)");
            } else if (n == "Camera") {
                need_options(d);
                read_camera(tokens, d);
            } else if (n == "Film") {
                need_options(d);
                read_film(tokens, d);
            } else if (n == "Sampler") {
                need_options(d);
                read_sampler(tokens, d);
            } else if (n == "Integrator") {
                need_options(d);
                read_integrator(tokens, d);
            } else if (n == "PixelFilter" || n == "Accelerator") {
                need_options(d);
                const std::string type = need_string(tokens, d, "type");
                ParamList p = ParamList::parse(tokens, n + " \"" + type + "\"");
                p.where = d.where;
                warn_ignored(p, n == "PixelFilter" ? "pixels are box-filtered"
                                                   : "the renderer builds its own BVH");
            } else if (n == "WorldBegin") {
                need_options(d);
                begin_world(d);
            } else if (n == "MakeNamedMedium" || n == "MediumInterface") {
                read_media(tokens, d);
            } else if (n == "Shape") {
                need_world(d);
                read_shape(tokens, d);
            } else if (n == "Material") {
                need_world(d);
                const std::string type = need_string(tokens, d, "material type");
                ParamList p = ParamList::parse(tokens, "Material \"" + type + "\"");
                p.where = d.where;
                state_.material = make_material(type, p, textures_, named_materials_, resolver());
            } else if (n == "MakeNamedMaterial") {
                need_world(d);
                const std::string name = need_string(tokens, d, "material name");
                ParamList p = ParamList::parse(tokens, "MakeNamedMaterial \"" + name + "\"");
                p.where = d.where;
                if (named_materials_.count(name))
                    throw SceneError(d.where, "named material \"" + name + "\" redefined");
                if (!p.has("type")) throw p.error("type", "\"string type\" is required");
                named_materials_[name] = make_material(p.get_string("type", ""), p, textures_,
                                                       named_materials_, resolver());
            } else if (n == "NamedMaterial") {
                need_world(d);
                const std::string name = need_string(tokens, d, "material name");
                auto it = named_materials_.find(name);
                if (it == named_materials_.end())
                    throw SceneError(d.where, "NamedMaterial: unknown material \"" + name +
                                                  "\" (MakeNamedMaterial must come first)");
                state_.material = it->second;
            } else if (n == "Texture") {
                need_world(d);
                read_texture(tokens, d);
            } else if (n == "LightSource") {
                need_world(d);
                const std::string type = need_string(tokens, d, "light type");
                ParamList p = ParamList::parse(tokens, "LightSource \"" + type + "\"");
                p.where = d.where;
                check_ray_transform(d);  // light paths start from it, as camera rays do
                std::unique_ptr<Light> light = make_light(type, p, state_.ctm, resolver());
                light->medium = state_.outside;
                scene_.add_light(std::move(light));
            } else if (n == "AreaLightSource") {
                need_world(d);
                const std::string type = need_string(tokens, d, "area light type");
                auto p = std::make_shared<ParamList>(
                    ParamList::parse(tokens, "AreaLightSource \"" + type + "\""));
                p->where = d.where;
                state_.area_light = AreaLightState{type, p};
            } else if (n == "ObjectBegin") {
                need_world(d);
                begin_object(need_string(tokens, d, "object name"), d);
            } else if (n == "ObjectEnd") {
                end_object(d);
            } else if (n == "ObjectInstance") {
                need_world(d);
                instantiate(need_string(tokens, d, "object name"), d);
            } else if (n == "Attribute") {
                throw SceneError(d.where, "Attribute: default parameters are not supported yet");
            } else if (n == "WorldEnd") {
                throw SceneError(d.where, n + " is a pbrt-v3 directive (pbrt-v4 removed it)");
            } else {
                throw SceneError(d.where, "unknown directive \"" + n + "\"");
            }
        }
    }

    // ----- options block -----

    void read_camera(Tokenizer& tokens, const Token& d) {
        if (camera_)
            throw SceneError(d.where,
                             "Camera given twice (first at " + camera_->where.to_string() + ")");
        const std::string type = need_string(tokens, d, "camera type");
        ParamList p = ParamList::parse(tokens, "Camera \"" + type + "\"");
        p.where = d.where;
        if (type != "perspective")
            throw SceneError(d.where,
                             "Camera \"" + type + "\" is not supported yet (only perspective)");
        // Camera rays start from its to_world (the inverse of the current transform): refused
        // here, naming this line, when rays could not pass through it.
        // A camera placed too far is told so first, as build_camera does.
        if (state_.ctm.is_singular())
            throw SceneError(d.where, "Camera: the transform is singular");
        const Transform to_world = state_.ctm.inverse();
        if (!within_scene_limits(to_world.apply_point(Vec3(0.0f))))
            throw SceneError(d.where, "the camera lies beyond 1e12 from the origin");
        if (const std::string problem = ray_transform_problem(to_world); !problem.empty())
            throw SceneError(d.where, "Camera: " + problem);
        camera_ = p;
        camera_from_world_ = state_.ctm;
        scene_.set_camera_medium(state_.outside);
        coordinate_systems_["camera"] = state_.ctm.inverse();
    }

    void read_film(Tokenizer& tokens, const Token& d) {
        if (have_film_) throw SceneError(d.where, "Film given twice");
        have_film_ = true;
        const std::string type = need_string(tokens, d, "film type");
        ParamList p = ParamList::parse(tokens, "Film \"" + type + "\"");
        p.where = d.where;
        if (type != "rgb")
            throw SceneError(d.where, "Film \"" + type + "\" is not supported (only rgb)");
        const long long w = p.get_int("xresolution", 1280), h = p.get_int("yresolution", 720);
        if (w < 1 || w > 65536) throw p.error("xresolution", "must be in [1, 65536]");
        if (h < 1 || h > 65536) throw p.error("yresolution", "must be in [1, 65536]");
        width_ = int(w), height_ = int(h);
        if (p.has("filename")) {
            p.get_string("filename", "");
            warn(p.find("filename")->where,
                 "Film \"filename\" is ignored (the output is named "
                 "by the renderer)");
        }
        if (p.has("savefp16")) {
            p.get_bool("savefp16", false);
            warn(p.find("savefp16")->where, "Film \"savefp16\" is ignored (float EXR is written)");
        }
        // The defaults of pbrt's sensor: anything else changes the image's scale or colour.
        if (p.get_string("sensor", "cie1931") != "cie1931")
            throw p.error("sensor", "only the cie1931 sensor is supported");
        if (p.get_float("iso", 100) != 100) throw p.error("iso", "only iso 100 is supported");
        if (p.get_float("whitebalance", 0) != 0)
            throw p.error("whitebalance", "white balancing is not supported");
        p.check_all_used();
    }

    void read_sampler(Tokenizer& tokens, const Token& d) {
        const std::string type = need_string(tokens, d, "sampler type");
        ParamList p = ParamList::parse(tokens, "Sampler \"" + type + "\"");
        p.where = d.where;
        static const std::set<std::string> kTypes = {
            "zsobol", "sobol", "paddedsobol", "halton", "pmj02bn", "independent", "stratified"};
        if (!kTypes.count(type)) throw SceneError(d.where, "unknown sampler \"" + type + "\"");
        long long spp = 0;
        if (type == "stratified") {
            p.get_bool("jitter", true);
            spp = p.get_int("xsamples", 4) * p.get_int("ysamples", 4);
        } else {
            spp = p.get_int("pixelsamples", 16);
            p.get_string("randomization", "");
        }
        p.get_int("seed", 0);  // the job's seed is used
        if (spp < 1 || spp > (1ll << 31) - 1)
            throw p.error(type == "stratified" ? "xsamples" : "pixelsamples",
                          "must be a positive integer");
        scene_.settings.sample_count = int(spp);
        p.check_all_used();
    }

    void read_integrator(Tokenizer& tokens, const Token& d) {
        const std::string type = need_string(tokens, d, "integrator type");
        ParamList p = ParamList::parse(tokens, "Integrator \"" + type + "\"");
        p.where = d.where;
        const long long depth = p.get_int("maxdepth", 5);
        if (depth < 0 || depth > 1000000) throw p.error("maxdepth", "must be non-negative");
        // pbrt counts scattering events (bounces); our max_depth counts path segments as
        // Mitsuba does (1 = only directly visible emitters, which is pbrt's maxdepth 0).
        scene_.settings.max_depth = int(depth) + 1;
        scene_.settings.integrator = integrator_name(type);
        for (const Param* u : p.unused())
            warn(u->where, p.context() + ": parameter \"" + u->name +
                               "\" is ignored (the algorithm and its options come from the "
                               "renderer)");
        have_integrator_ = true;
    }

    void begin_world(const Token& d) {
        if (world_) throw SceneError(d.where, "WorldBegin given twice");
        world_ = true;
        if (!have_integrator_) {
            // pbrt-v4's default integrator.
            scene_.settings.integrator = integrator_name("volpath");
            scene_.settings.max_depth = 6;
        }
        build_camera(d);
        state_.ctm = Transform();
        coordinate_systems_["world"] = Transform();
    }

    void build_camera(const Token& d) {
        ParamList p = camera_ ? *camera_ : ParamList();
        if (!camera_) p.where = d.where;
        const double fov = p.get_float("fov", 90.0);
        if (!(fov > 0 && fov < 180)) throw p.error("fov", "must be in (0, 180) degrees");
        // pbrt-v4's thin lens (defaults: no lens, focus at 1e6).
        const double lens_radius = p.get_float("lensradius", 0.0);
        const double focal_distance = p.get_float("focaldistance", 1e6);
        if (!(lens_radius >= 0 && std::isfinite(lens_radius)))
            throw p.error("lensradius", "must be finite and >= 0");
        if (lens_radius > 0 && !(focal_distance > 0 && std::isfinite(focal_distance)))
            throw p.error("focaldistance", "must be positive");
        p.get_float("shutteropen", 0.0);  // no effect without motion
        p.get_float("shutterclose", 1.0);
        if (p.has("frameaspectratio") || p.has("screenwindow"))
            throw p.error(p.has("screenwindow") ? "screenwindow" : "frameaspectratio",
                          "is not supported yet");
        p.check_all_used();
        // pbrt's camera space has +x to the image's right; ours (Mitsuba's) to the left.
        Transform to_world = camera_from_world_.inverse() * Transform::scale(Vec3(-1, 1, 1));
        if (camera_from_world_.is_singular())
            throw SceneError(p.where, "the camera transform is singular");
        // pbrt: fov spans the shorter image axis.
        const char axis = width_ > height_ ? 'y' : 'x';
        PerspectiveCamera camera(to_world, float(fov), axis, width_, height_);
        if (lens_radius > 0) camera.set_thin_lens(float(lens_radius), float(focal_distance));
        if (!within_scene_limits(camera.position()))
            throw SceneError(p.where, "the camera lies beyond 1e12 from the origin");
        scene_.set_camera(camera);
    }

    // ----- world block -----

    void read_media(Tokenizer& tokens, const Token& d) {
        if (d.text == "MediumInterface") {
            // One name (inside and outside alike) or two: inside, outside. "" is vacuum.
            const Token first = need_token(tokens, d, "interior medium");
            if (!first.quoted)
                throw SceneError(first.where, "MediumInterface: expected a quoted medium name");
            Token second = first;
            if (tokens.peek() && tokens.peek()->quoted) second = *tokens.next();
            state_.inside = lookup_medium(first);
            state_.outside = lookup_medium(second);
            return;
        }
        const std::string name = need_string(tokens, d, "medium name");
        ParamList p = ParamList::parse(tokens, "MakeNamedMedium \"" + name + "\"");
        p.where = d.where;
        if (media_.count(name)) throw SceneError(d.where, "medium \"" + name + "\" redefined");
        if (!p.has("type")) throw p.error("type", "\"string type\" is required");
        media_[name] = scene_.add_medium(make_medium(p.get_string("type", ""), p, state_.ctm));
    }

    const Medium* lookup_medium(const Token& name) const {
        if (name.text.empty()) return nullptr;
        auto it = media_.find(name.text);
        if (it == media_.end())
            throw SceneError(name.where, "MediumInterface: unknown medium \"" + name.text +
                                             "\" (MakeNamedMedium must come first)");
        return it->second;
    }

    void read_shape(Tokenizer& tokens, const Token& d) {
        const std::string type = need_string(tokens, d, "shape type");
        ParamList p = ParamList::parse(tokens, "Shape \"" + type + "\"");
        p.where = d.where;
        if (object_ && state_.area_light)
            throw SceneError(d.where, "Shape inside ObjectBegin \"" + object_->name() +
                                          "\": area lights in object instances are not "
                                          "supported (nor are they in pbrt-v4)");
        check_ray_transform(d);
        if (type == "curve" && state_.area_light)
            throw SceneError(d.where,
                             "Shape \"curve\": an area light on a curve is not supported "
                             "(a flat curve faces each ray, so it has no surface to "
                             "sample by area; pbrt-v4 implements no Curve::Sample "
                             "either)");
        std::shared_ptr<const AlphaCutout> alpha = read_alpha(p);
        if (alpha && state_.area_light)
            throw p.error("alpha",
                          "an area light with an alpha cut-out is not supported yet (the "
                          "light's sampling does not know the cut-out)");
        std::vector<std::unique_ptr<Shape>> shapes =
            make_shapes(type, p, state_.ctm, state_.reverse_orientation, resolver());
        if (!state_.material) {
            // pbrt-v4's default material: diffuse, reflectance 0.5.
            ParamList none;
            none.where = d.where;
            state_.material =
                make_material("diffuse", none, textures_, named_materials_, resolver());
        }
        for (std::unique_ptr<Shape>& shape : shapes) {
            shape->alpha = alpha;
            check_extent(*shape, d);
            std::unique_ptr<Light> light;
            if (state_.area_light) {
                light = make_area_light(state_.area_light->type, *state_.area_light->params,
                                        shape.get(), resolver());
                shape->emitter = light.get();
                light->medium = state_.outside;  // it emits on its outside
            }
            // pbrt: a shape is a medium boundary only when the media on its sides differ.
            if (state_.inside != state_.outside) {
                shape->interior = state_.inside;
                shape->exterior = state_.outside;
            }
            if (object_) {
                object_->add(std::move(shape), keep(state_.material));
                continue;
            }
            scene_.add_shape(std::move(shape), keep(state_.material));
            if (light) scene_.add_light(std::move(light));
        }
    }

    // pbrt-v4's `alpha`: a float or a float texture; null for an opaque shape (alpha 1).
    std::shared_ptr<const AlphaCutout> read_alpha(const ParamList& p) const {
        if (!p.has("alpha")) return nullptr;
        FloatParam alpha;
        if (p.type_of("alpha") == "texture") {
            const Param* a = p.find("alpha");
            a->used = true;
            if (a->strings.size() != 1) throw p.error("alpha", "expects one texture name");
            auto it = textures_.floats.find(a->strings[0]);
            if (it == textures_.floats.end())
                throw p.error("alpha", "unknown float texture \"" + a->strings[0] +
                                           "\" (a texture must be defined before it is used)");
            alpha.texture = it->second;
        } else {
            const double value = p.get_float("alpha", 1.0);
            if (!std::isfinite(value)) throw p.error("alpha", "must be finite");
            if (value >= 1) return nullptr;
            alpha.value = float(value);
        }
        return std::make_shared<AlphaCutout>(std::move(alpha));
    }

    // ----- object instancing (core/shapes/instance.h) -----

    // ObjectBegin "name": an attribute block whose shapes, each with the transform current at
    // it, form the object.
    void begin_object(const std::string& name, const Token& d) {
        if (object_)
            throw SceneError(d.where, "ObjectBegin \"" + name + "\" inside ObjectBegin \"" +
                                          object_->name() + "\" (objects cannot nest)");
        if (objects_.count(name))
            throw SceneError(d.where, "ObjectBegin: object \"" + name + "\" redefined");
        attributes_.emplace_back(state_, d.where);
        object_ = std::make_shared<ShapeGroup>(name);
        object_where_ = d.where;
        object_depth_ = attributes_.size();
    }

    void end_object(const Token& d) {
        if (!object_) throw SceneError(d.where, "ObjectEnd without ObjectBegin");
        if (attributes_.size() != object_depth_)
            throw SceneError(d.where,
                             "ObjectEnd: AttributeBegin and AttributeEnd inside the "
                             "object do not balance");
        state_ = attributes_.back().first;
        attributes_.pop_back();
        objects_[object_->name()] = std::move(object_);
        object_.reset();
    }

    // ObjectInstance "name": the object's shapes placed with the current transform (which
    // applies after each shape's own).
    void instantiate(const std::string& name, const Token& d) {
        if (object_)
            throw SceneError(d.where, "ObjectInstance inside ObjectBegin \"" + object_->name() +
                                          "\" (objects cannot nest)");
        auto it = objects_.find(name);
        if (it == objects_.end())
            throw SceneError(d.where, "ObjectInstance: unknown object \"" + name +
                                          "\" (ObjectBegin must come first)");
        check_ray_transform(d);
        if (it->second->empty()) {
            warn(d.where, "ObjectInstance: object \"" + name + "\" has no shapes");
            return;
        }
        auto instance = std::make_unique<Instance>(
            it->second, state_.ctm, "object \"" + name + "\" (" + d.where.to_string() + ")");
        if (!within_scene_limits(*instance))
            throw SceneError(d.where,
                             "ObjectInstance: its geometry reaches beyond 1e12 from the "
                             "origin or is not finite (check the transform)");
        scene_.add_instance(std::move(instance));
    }

    // Refuses a current transform rays could not pass through at the directive that uses it
    // (ray_transform_problem, core/base/ray_transform_check.h).
    void check_ray_transform(const Token& d) const {
        if (const std::string problem = ray_transform_problem(state_.ctm); !problem.empty())
            throw SceneError(d.where, d.text + ": " + problem);
    }

    // Refuses geometry beyond the scene's limits (within_scene_limits, core/scene/scene.h).
    static void check_extent(const Shape& shape, const Token& d) {
        if (!within_scene_limits(shape))
            throw SceneError(d.where,
                             "Shape: its geometry reaches beyond 1e12 from the origin or "
                             "is not finite (check the transform)");
    }

    void read_texture(Tokenizer& tokens, const Token& d) {
        const std::string name = need_string(tokens, d, "texture name");
        const std::string kind = need_string(tokens, d, "texture type (spectrum or float)");
        const std::string cls = need_string(tokens, d, "texture class");
        ParamList p = ParamList::parse(tokens, "Texture \"" + name + "\" \"" + cls + "\"");
        p.where = d.where;
        if (kind != "spectrum" && kind != "float")
            throw SceneError(d.where, "Texture \"" + name +
                                          "\": the type must be \"spectrum\" "
                                          "or \"float\", not \"" +
                                          kind + "\"");
        auto& table = kind == "spectrum" ? textures_.spectrum : textures_.floats;
        if (table.count(name)) throw SceneError(d.where, "Texture \"" + name + "\" redefined");
        table[name] = make_texture(cls, p, textures_, resolver());
    }

    Scene& scene_;
    fs::path scene_dir_;
    FolderConfinement confinement_;
    std::set<std::string> open_files_;
    GraphicsState state_;
    std::vector<std::pair<GraphicsState, SourceLocation>> attributes_;
    std::map<std::string, std::shared_ptr<const ShapeGroup>> objects_;
    std::shared_ptr<ShapeGroup> object_;  // the object being defined (ObjectBegin)
    SourceLocation object_where_;
    size_t object_depth_ = 0;  // attributes_.size() just after its ObjectBegin
    std::vector<Transform> transforms_;
    std::map<std::string, Transform> coordinate_systems_;
    std::map<std::string, std::shared_ptr<const Bsdf>> named_materials_;
    std::map<std::string, const Medium*> media_;
    TextureTable textures_;
    std::set<const Bsdf*> kept_;
    std::optional<ParamList> camera_;
    Transform camera_from_world_;
    int width_ = 1280, height_ = 720;
    bool have_film_ = false, have_integrator_ = false, world_ = false;
};

std::unique_ptr<Scene> load(const std::function<void(Loader&)>& run, const fs::path& dir,
                            const std::string& name, const fs::path& confine_to) {
    auto scene = std::make_unique<Scene>();
    scene->source_file = name;
    try {
        Loader loader(*scene, dir, confine_to);
        run(loader);
        loader.finish(name);
        scene->commit();
    } catch (const SceneError&) {
        throw;
    } catch (const std::exception& ex) {
        throw SceneError(SourceLocation{name, 0}, ex.what());
    }
    return scene;
}

}  // namespace

std::string integrator_name(const std::string& pbrt) {
    return "pbrt:" + pbrt;
}

std::unique_ptr<Scene> load_scene(const fs::path& file, const fs::path& confine_to) {
    const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
    return load(
        [&](Loader& l) {
            l.run_file(file, SourceLocation{file.string(), 0}, 0);
        },
        dir, file.string(), confine_to);
}

std::unique_ptr<Scene> load_scene_from_string(const std::string& text, const fs::path& base_dir) {
    return load([&](Loader& l) { l.run_text(text, "<string>"); },
                base_dir.empty() ? fs::path(".") : base_dir, "<string>", {});
}

}  // namespace render::pbrt
