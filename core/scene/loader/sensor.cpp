// <sensor> (a perspective camera, its medium), its <film>, <rfilter> and <sampler>.

#include <cmath>
#include <iostream>

#include "core/scene/loader/xml_loader.h"

namespace render::mitsuba {
namespace {

// Known sampler plugins; all are rendered with independent samples.
constexpr const char* kSamplerTypes[] = {"independent", "stratified", "multijitter", "orthogonal",
                                         "ldsampler",   "halton",     "sobol"};

}  // namespace

void Loader::read_sensor(const XmlElement& e) {
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
    if (props.type() != "perspective" && props.type() != "thinlens")
        throw SceneError(e.where(), "unknown sensor type \"" + props.type() +
                                        "\" (supported: perspective, thinlens)");
    PerspectiveCamera camera = build(props, [&] {
        float fov = 0;
        char fov_axis = 'x';
        if (props.has("fov") && props.has("focal_length"))
            throw props.error("focal_length", "give either \"fov\" or \"focal_length\"");
        if (props.has("fov")) {
            fov = props.get_float("fov");
            if (!(fov > 0 && fov < 180)) throw props.error("fov", "must be in (0, 180) degrees");
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
        if (!(far_clip > near_clip)) throw props.error("far_clip", "must be larger than near_clip");
        // Mitsuba's projective cameras all read `focus_distance`; a pinhole has no focus,
        // so the value has no effect there (as in Mitsuba), but it must be a number.
        const float focus_distance = props.get_float("focus_distance", far_clip);
        float aperture_radius = 0;
        if (props.type() == "thinlens") {
            // Mitsuba's thinlens: `aperture_radius` is required (its zero becomes a pinhole).
            aperture_radius = props.get_float("aperture_radius");
            if (!(aperture_radius >= 0 && std::isfinite(aperture_radius)))
                throw props.error("aperture_radius", "must be finite and >= 0");
            if (!(focus_distance > 0 && std::isfinite(focus_distance)))
                throw props.error("focus_distance", "must be positive");
        }
        // A shifted principal point (off-axis projection) is not implemented; the zero
        // offsets exporters write are the identity.
        for (const char* name : {"principal_point_offset_x", "principal_point_offset_y"})
            if (props.get_float(name, 0.0f) != 0.0f)
                throw props.error(name, "a non-zero principal point offset is not supported yet");
        const Transform to_world = props.get_transform("to_world", Transform());
        if (to_world.is_singular()) throw props.error("to_world", "the transform is singular");
        PerspectiveCamera camera(to_world, fov, fov_axis, width, height);
        if (aperture_radius > 0) {
            // As Mitsuba: the lens lives in camera units, which must be the world's.
            for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)})
                if (std::abs(length(to_world.apply_vector(axis)) - 1.0f) > 1e-3f)
                    throw props.error("to_world", "a thinlens camera's transform may not scale");
            camera.set_thin_lens(aperture_radius, focus_distance);
        }
        if (!within_scene_limits(camera.position()))
            throw props.error("to_world", "places the camera beyond 1e12 from the origin");
        // Camera rays start from to_world: refused at its line when near-singular, as a
        // shape's (ray_transform_problem, core/base/ray_transform_check.h).
        props.get_ray_transform("to_world");
        return camera;
    });
    scene_.set_camera(camera);
    scene_.set_camera_medium(camera_medium);
    have_sensor_ = true;
    sensor_where_ = e.where();
}

// `focal_length` ("50mm" as Mitsuba writes it, or a number of millimetres; default 50 mm)
// as the diagonal field of view of a 36 x 24 mm film, in degrees.
float Loader::fov_from_focal_length(const Properties& props) {
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

void Loader::read_film(const XmlElement& e, int& width, int& height) {
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

void Loader::read_rfilter(const XmlElement& e) {
    Properties props = read_plain_object(e, "rfilter");
    // Every value is read (validated) but ignored.
    if (props.type() != "box" && !warned_rfilter_) {
        std::cerr << "warning: " << e.where().to_string()
                  << ": reconstruction filters are ignored (a box filter is used)\n";
        warned_rfilter_ = true;
    }
}

void Loader::read_sampler(const XmlElement& e) {
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

}  // namespace render::mitsuba
