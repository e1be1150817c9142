#pragma once

// The parameters of one scene-file plugin (Mitsuba's Properties): typed named values plus
// nested objects. Every read marks the value as used; once a plugin is built the parser calls
// check_all_used() so that a misspelt or unsupported parameter is an error naming its line,
// as pbrt and Mitsuba do.

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "core/base/error.h"
#include "core/math/transform.h"
#include "core/math/vec.h"

namespace render {

class Bsdf;
class Texture;

class Properties {
  public:
    using Value = std::variant<bool, int64_t, float, std::string, Rgb, Vec3, Transform,
                               std::shared_ptr<const Texture>>;

    Properties(std::string plugin_class, std::string plugin_type, SourceLocation where)
        : class_(std::move(plugin_class)),
          type_(std::move(plugin_type)),
          where_(std::move(where)) {}

    // e.g. class "bsdf", type "diffuse"
    const std::string& plugin_class() const { return class_; }
    const std::string& type() const { return type_; }
    const SourceLocation& where() const { return where_; }
    std::string id;  // optional `id` attribute

    // Adds a value; a second value of the same name is an error.
    void set(const std::string& name, Value value, const SourceLocation& where);
    bool has(const std::string& name) const { return values_.count(name) != 0; }

    // Typed getters. The versions without a default throw a SceneError naming the plugin when
    // the value is missing; all throw when the value has another type. get_float accepts an
    // integer; get_rgb accepts a float (grey).
    bool get_bool(const std::string& name) const;
    bool get_bool(const std::string& name, bool def) const;
    int64_t get_int(const std::string& name) const;
    int64_t get_int(const std::string& name, int64_t def) const;
    float get_float(const std::string& name) const;
    float get_float(const std::string& name, float def) const;
    std::string get_string(const std::string& name) const;
    std::string get_string(const std::string& name, const std::string& def) const;
    Rgb get_rgb(const std::string& name) const;
    Rgb get_rgb(const std::string& name, const Rgb& def) const;
    Vec3 get_vec3(const std::string& name) const;  // `point` or `vector`
    Vec3 get_vec3(const std::string& name, const Vec3& def) const;
    Transform get_transform(const std::string& name) const;
    Transform get_transform(const std::string& name, const Transform& def) const;
    // A transform rays pass through (a shape's, an instance's, a volume grid's): refused at its
    // line unless ray_transform_problem (core/base/ray_transform_check.h) accepts it.
    Transform get_ray_transform(const std::string& name) const;
    // A nested or referenced <texture> given for `name` (never null), or null when the value
    // is absent or a plain value (which the typed getters then read; nothing is marked read).
    std::shared_ptr<const Texture> get_texture(const std::string& name) const;

    // Where a named value was written (the plugin's own location if absent).
    SourceLocation where(const std::string& name) const;

    // Nested BSDFs (for wrappers such as `twosided`), in file order.
    std::vector<std::shared_ptr<const Bsdf>> nested_bsdfs;

    // An error about parameter `name` of this plugin, located at that parameter's line.
    SceneError error(const std::string& name, const std::string& message) const;
    // Throws a SceneError naming the first value nobody read.
    void check_all_used() const;
    // The names of the values nobody read yet, with where they were written (for plugins that
    // ignore some parameters with a warning instead of refusing them).
    std::vector<std::pair<std::string, SourceLocation>> unused() const;
    // Marks every value as read.
    void mark_all_used() const;

    // The string value of `name` without marking it read; null when absent or not a string.
    const std::string* peek_string(const std::string& name) const;
    // Replaces the value of an existing string parameter, keeping its location and whether it
    // was read (the loader rewrites `filename` to the file it resolved).
    void replace_string(const std::string& name, std::string value);

  private:
    struct Entry {
        Value value;
        SourceLocation where;
        mutable bool used = false;
    };
    const Entry* find(const std::string& name) const;
    template <typename T>
    T get_as(const std::string& name, const char* type_name) const;

    std::string class_;
    std::string type_;
    SourceLocation where_;
    std::map<std::string, Entry> values_;
};

}  // namespace render
