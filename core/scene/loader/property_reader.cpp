#include "core/scene/loader/property_reader.h"

#include <cctype>
#include <cmath>
#include <iostream>
#include <sstream>

#include "core/image/spectrum.h"

#include "core/scene/loader/values.h"

namespace render {
namespace {

std::string field_name(const XmlElement& e) {
    std::optional<std::string> name = e.optional("name");
    return e.tag() + " \"" + (name ? *name : std::string()) + "\"";
}

Vec3 to_vec3(const std::vector<double>& v) {
    return Vec3(float(v[0]), float(v[1]), float(v[2]));
}

// `value="x, y, z"` or x/y/z attributes (each defaulting to `def`).
Vec3 read_xyz(const XmlElement& e, const std::string& field, float def) {
    if (std::optional<std::string> value = e.optional("value")) {
        if (e.has("x") || e.has("y") || e.has("z"))
            throw SceneError(e.where(), field + ": give either value or x/y/z, not both");
        std::vector<double> v = parse_number_list(*value, e.where(), field);
        if (v.size() != 3)
            throw SceneError(e.where(),
                             field + ": value needs 3 numbers, got " + std::to_string(v.size()));
        return to_vec3(v);
    }
    Vec3 out(def);
    const char* names[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i)
        if (std::optional<std::string> s = e.optional(names[i]))
            out[i] = float(parse_number(*s, e.where(), field + " " + names[i]));
    return out;
}

Vec3 read_point_attribute(const XmlElement& e, const char* attr, const std::string& field) {
    std::vector<double> v =
        parse_number_list(e.required(attr), e.where(), field + " " + std::string(attr));
    if (v.size() != 3)
        throw SceneError(e.where(),
                         field + ": " + attr + " needs 3 numbers, got " + std::to_string(v.size()));
    return to_vec3(v);
}

Transform read_transform_step(const XmlElement& e) {
    const std::string tag = e.tag();
    const std::string field = "<" + tag + ">";
    if (!e.children().empty()) throw SceneError(e.where(), field + " cannot have child elements");
    if (tag == "matrix") {
        e.check_attributes({"value"});
        std::vector<double> v = parse_number_list(e.required("value"), e.where(), field);
        if (v.size() != 16)
            throw SceneError(e.where(), field + ": value needs 16 numbers (row-major 4x4), got " +
                                            std::to_string(v.size()));
        Transform::Matrix m;
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) m[size_t(r)][size_t(c)] = v[size_t(4 * r + c)];
        return Transform(m);
    }
    if (tag == "translate") {
        e.check_attributes({"x", "y", "z", "value"});
        return Transform::translate(read_xyz(e, field, 0.0f));
    }
    if (tag == "scale") {
        e.check_attributes({"x", "y", "z", "value"});
        if (std::optional<std::string> value = e.optional("value")) {
            std::vector<double> v = parse_number_list(*value, e.where(), field);
            if (v.size() == 1) return Transform::scale(Vec3(float(v[0])));
        }
        return Transform::scale(read_xyz(e, field, 1.0f));
    }
    if (tag == "rotate") {
        e.check_attributes({"x", "y", "z", "value", "angle"});
        Vec3 axis = read_xyz(e, field, 0.0f);
        if (length_squared(axis) == 0)
            throw SceneError(e.where(), field + ": the rotation axis is zero");
        float angle = float(parse_number(e.required("angle"), e.where(), field + " angle"));
        return Transform::rotate(axis, angle);
    }
    if (tag == "lookat") {
        e.check_attributes({"origin", "target", "up"});
        Vec3 origin = read_point_attribute(e, "origin", field);
        Vec3 target = read_point_attribute(e, "target", field);
        Vec3 dir = target - origin;
        if (length_squared(dir) == 0)
            throw SceneError(e.where(), field + ": origin and target are the same point");
        dir = normalize(dir);
        Vec3 up;
        if (e.has("up")) {
            up = read_point_attribute(e, "up", field);
        } else {
            // Any direction perpendicular to dir (Mitsuba's coordinate_system).
            up =
                std::abs(dir.x) > std::abs(dir.z) ? Vec3(-dir.y, dir.x, 0) : Vec3(0, -dir.z, dir.y);
        }
        if (length_squared(up) == 0 || length_squared(cross(normalize(up), dir)) < 1e-12f)
            throw SceneError(e.where(), field + ": up is zero or parallel to the view direction");
        return Transform::look_at(origin, target, up);
    }
    throw SceneError(e.where(), "unknown tag <" + tag +
                                    "> in <transform> (expected matrix, lookat, translate, "
                                    "scale or rotate)");
}

bool is_finite_transform(const Transform& t) {
    for (const auto& row : t.matrix())
        for (double x : row)
            if (!std::isfinite(x)) return false;
    return true;
}

// Mitsuba's unbounded spectra (src/core/xml.cpp, is_unbounded_spectrum): not clamped to 1,
// and never an emission.
bool is_unbounded_spectrum(const std::string& name) {
    return name == "eta" || name == "k" || name == "int_ior" || name == "ext_ior" ||
           name == "sigma_t";
}

// A wavelength:value spectrum converted as Mitsuba 3's RGB variants do
// (docs/reference/scene-format.md, "Spectra"): integrated against the CIE 1931 curves (weighted by
// D65 unless emitted) and converted to linear sRGB; clamped colours print a warning.
void set_spectrum(const std::string& name, const std::string& field, const SourceLocation& where,
                  const std::vector<double>& wavelengths, const std::vector<double>& values,
                  Properties& props) {
    const bool emitted = props.plugin_class() == "emitter" && !is_unbounded_spectrum(name);
    const SpectrumToRgb rgb = spectrum_to_linear_srgb(wavelengths, values, !emitted,
                                                      !emitted && !is_unbounded_spectrum(name));
    if (rgb.clamped) {
        std::ostringstream message;
        message << "warning: " << where.to_string() << ": " << field
                << ": the spectrum's colour is outside the "
                << (emitted || is_unbounded_spectrum(name) ? "non-negative" : "[0, 1]")
                << " range of linear sRGB and was clamped to " << rgb.rgb << " (as Mitsuba does)\n";
        std::cerr << message.str();
    }
    props.set(name, rgb.rgb, where);
}

// <spectrum name="n" value="v"/> or value="w1:v1, w2:v2, ...": a single value is grey, but
// directly inside an <emitter> it is v times the sRGB colour of XYZ (1, 1, 1); a list goes
// through set_spectrum.
void read_spectrum(const XmlElement& e, const std::string& name, const std::string& field,
                   Properties& props) {
    const SourceLocation where = e.where();
    if (e.has("filename"))
        throw SceneError(where, field +
                                    ": a spectrum file (filename) needs the scene loader, which "
                                    "resolves it");
    e.check_attributes({"name", "value"});
    const std::string value = e.required("value");
    const bool emitted = props.plugin_class() == "emitter" && !is_unbounded_spectrum(name);
    if (value.find(':') == std::string::npos) {
        std::vector<double> v = parse_number_list(value, where, field);
        if (v.size() != 1)
            throw SceneError(where, field +
                                        ": a spectrum is one number or wavelength:value pairs "
                                        "(\"400:0.1, 700:0.5\"); use <rgb> for colours");
        if (emitted)
            props.set(name, xyz_to_linear_srgb(1, 1, 1) * float(v[0]), where);
        else
            props.set(name, float(v[0]), where);
        return;
    }
    std::vector<double> wavelengths, values;
    std::string token;
    auto add_pair = [&]() {
        if (token.empty()) return;
        const size_t colon = token.find(':');
        if (colon == std::string::npos || token.find(':', colon + 1) != std::string::npos)
            throw SceneError(where, field + ": \"" + token +
                                        "\" is not a wavelength:value pair (a spectrum is one "
                                        "number or pairs \"400:0.1, 700:0.5\")");
        const double w =
            parse_number(std::string_view(token).substr(0, colon), where, field + " wavelength");
        const double v =
            parse_number(std::string_view(token).substr(colon + 1), where, field + " value");
        if (!wavelengths.empty() && !(w > wavelengths.back()))
            throw SceneError(where, field + ": wavelengths must increase (" + std::to_string(w) +
                                        " after " + std::to_string(wavelengths.back()) + ")");
        wavelengths.push_back(w);
        values.push_back(v);
        token.clear();
    };
    for (char c : value) {
        if (c == ',' || std::isspace(static_cast<unsigned char>(c)))
            add_pair();
        else
            token += c;
    }
    add_pair();
    if (wavelengths.size() < 2)
        throw SceneError(where, field + ": a wavelength:value spectrum needs at least two pairs");
    set_spectrum(name, field, where, wavelengths, values, props);
}

}  // namespace

bool is_property_tag(std::string_view tag) {
    for (std::string_view t : {"integer", "float", "boolean", "string", "rgb", "spectrum", "point",
                               "vector", "transform"})
        if (t == tag) return true;
    return false;
}

Transform read_transform(const XmlElement& e) {
    Transform t;
    for (const XmlElement& step : e.children()) t = read_transform_step(step) * t;
    if (!is_finite_transform(t))
        throw SceneError(e.where(), field_name(e) + ": the composed transform is not finite");
    return t;
}

void read_property(const XmlElement& e, Properties& props) {
    const std::string tag = e.tag();
    const std::string name = e.required("name");
    if (name.empty()) throw SceneError(e.where(), "<" + tag + "> has an empty name");
    const std::string field = field_name(e);
    const SourceLocation where = e.where();
    if (tag != "transform" && !e.children().empty())
        throw SceneError(where, field + " cannot have child elements");

    if (tag == "integer") {
        e.check_attributes({"name", "value"});
        props.set(name, parse_integer(e.required("value"), where, field), where);
    } else if (tag == "float") {
        e.check_attributes({"name", "value"});
        props.set(name, float(parse_number(e.required("value"), where, field)), where);
    } else if (tag == "boolean") {
        e.check_attributes({"name", "value"});
        props.set(name, parse_boolean(e.required("value"), where, field), where);
    } else if (tag == "string") {
        e.check_attributes({"name", "value"});
        props.set(name, e.required("value"), where);
    } else if (tag == "rgb") {
        e.check_attributes({"name", "value"});
        std::vector<double> v = parse_number_list(e.required("value"), where, field);
        if (v.size() == 1) v = {v[0], v[0], v[0]};
        if (v.size() != 3)
            throw SceneError(
                where, field + ": value needs 1 or 3 numbers, got " + std::to_string(v.size()));
        props.set(name, Rgb(float(v[0]), float(v[1]), float(v[2])), where);
    } else if (tag == "spectrum") {
        read_spectrum(e, name, field, props);
    } else if (tag == "point" || tag == "vector") {
        e.check_attributes({"name", "value", "x", "y", "z"});
        props.set(name, read_xyz(e, field, 0.0f), where);
    } else if (tag == "transform") {
        e.check_attributes({"name"});
        props.set(name, read_transform(e), where);
    } else {
        throw SceneError(where, "<" + tag + "> is not a property tag");
    }
}

void read_spectrum_file(const XmlElement& e, const std::string& text, const std::string& file_name,
                        Properties& props) {
    e.check_attributes({"name", "filename"});
    const std::string name = e.required("name");
    const std::string field = "spectrum \"" + name + "\"";
    std::vector<double> wavelengths, values;
    size_t line_number = 0, begin = 0;
    while (begin < text.size()) {
        size_t end = text.find('\n', begin);
        if (end == std::string::npos) end = text.size();
        std::string_view line(text.data() + begin, end - begin);
        begin = end + 1;
        ++line_number;
        if (const size_t hash = line.find('#'); hash != std::string_view::npos)
            line = line.substr(0, hash);
        const SourceLocation at{file_name, int(line_number)};
        std::vector<double> numbers;
        std::string token;
        auto flush = [&] {
            if (!token.empty()) numbers.push_back(parse_number(token, at, field));
            token.clear();
        };
        for (char c : line) {
            if (c == ',' || std::isspace(static_cast<unsigned char>(c)))
                flush();
            else
                token += c;
        }
        flush();
        if (numbers.empty()) continue;
        if (numbers.size() != 2)
            throw SceneError(at, field +
                                     ": a line of a spectrum file is \"wavelength value\", "
                                     "got " +
                                     std::to_string(numbers.size()) + " numbers");
        if (!wavelengths.empty() && !(numbers[0] > wavelengths.back()))
            throw SceneError(at, field + ": wavelengths must increase (" +
                                     std::to_string(numbers[0]) + " after " +
                                     std::to_string(wavelengths.back()) + ")");
        wavelengths.push_back(numbers[0]);
        values.push_back(numbers[1]);
        if (wavelengths.size() > 100000)
            throw SceneError(at, field + ": more than 100000 wavelengths");
    }
    if (wavelengths.size() < 2)
        throw SceneError(e.where(), field + ": the spectrum file " + file_name +
                                        " needs at least two \"wavelength value\" lines");
    set_spectrum(name, field, e.where(), wavelengths, values, props);
}

}  // namespace render
