#include "core/base/properties.h"

#include "core/base/ray_transform_check.h"
#include "core/base/scene_limits.h"

namespace render {

void Properties::set(const std::string& name, Value value, const SourceLocation& where) {
    auto [it, inserted] = values_.emplace(name, Entry{std::move(value), where});
    if (!inserted)
        throw SceneError(where, "parameter \"" + name + "\" of " + class_ + " \"" + type_ +
                                    "\" is given twice (first at " + it->second.where.to_string() +
                                    ")");
}

const Properties::Entry* Properties::find(const std::string& name) const {
    auto it = values_.find(name);
    if (it == values_.end()) return nullptr;
    it->second.used = true;
    return &it->second;
}

SourceLocation Properties::where(const std::string& name) const {
    auto it = values_.find(name);
    return it == values_.end() ? where_ : it->second.where;
}

SceneError Properties::error(const std::string& name, const std::string& message) const {
    return SceneError(where(name),
                      class_ + " \"" + type_ + "\", parameter \"" + name + "\": " + message);
}

template <typename T>
T Properties::get_as(const std::string& name, const char* type_name) const {
    const Entry* e = find(name);
    if (!e)
        throw SceneError(where_, class_ + " \"" + type_ + "\" needs parameter \"" + name + "\"");
    if (const T* v = std::get_if<T>(&e->value)) return *v;
    if (std::holds_alternative<std::shared_ptr<const Texture>>(e->value))
        throw error(name, std::string("a texture is not accepted here (expected a value of type ") +
                              type_name + ")");
    throw error(name, std::string("expected a value of type ") + type_name);
}

bool Properties::get_bool(const std::string& name) const {
    return get_as<bool>(name, "boolean");
}
bool Properties::get_bool(const std::string& name, bool def) const {
    return has(name) ? get_bool(name) : def;
}

int64_t Properties::get_int(const std::string& name) const {
    return get_as<int64_t>(name, "integer");
}
int64_t Properties::get_int(const std::string& name, int64_t def) const {
    return has(name) ? get_int(name) : def;
}

float Properties::get_float(const std::string& name) const {
    const Entry* e = find(name);
    if (e)
        if (const int64_t* i = std::get_if<int64_t>(&e->value)) return float(*i);
    return get_as<float>(name, "float");
}
float Properties::get_float(const std::string& name, float def) const {
    return has(name) ? get_float(name) : def;
}

std::string Properties::get_string(const std::string& name) const {
    return get_as<std::string>(name, "string");
}
std::string Properties::get_string(const std::string& name, const std::string& def) const {
    return has(name) ? get_string(name) : def;
}

Rgb Properties::get_rgb(const std::string& name) const {
    const Entry* e = find(name);
    if (e) {
        if (const float* f = std::get_if<float>(&e->value)) return Rgb(*f);
        if (const int64_t* i = std::get_if<int64_t>(&e->value)) return Rgb(float(*i));
    }
    return get_as<Rgb>(name, "rgb");
}
Rgb Properties::get_rgb(const std::string& name, const Rgb& def) const {
    return has(name) ? get_rgb(name) : def;
}

Vec3 Properties::get_vec3(const std::string& name) const {
    return get_as<Vec3>(name, "point/vector");
}
Vec3 Properties::get_vec3(const std::string& name, const Vec3& def) const {
    return has(name) ? get_vec3(name) : def;
}

Transform Properties::get_transform(const std::string& name) const {
    return get_as<Transform>(name, "transform");
}
Transform Properties::get_transform(const std::string& name, const Transform& def) const {
    return has(name) ? get_transform(name) : def;
}

Transform Properties::get_ray_transform(const std::string& name) const {
    const Transform t = get_transform(name, Transform());
    if (const std::string problem = ray_transform_problem(t); !problem.empty())
        throw error(name, problem);
    return t;
}

std::shared_ptr<const Texture> Properties::get_texture(const std::string& name) const {
    auto it = values_.find(name);
    if (it == values_.end()) return nullptr;
    const auto* texture = std::get_if<std::shared_ptr<const Texture>>(&it->second.value);
    if (!texture) return nullptr;
    it->second.used = true;
    return *texture;
}

void Properties::check_all_used() const {
    for (const auto& [name, entry] : values_)
        if (!entry.used)
            throw SceneError(entry.where, "unused parameter \"" + name + "\" in " + class_ + " \"" +
                                              type_ +
                                              "\" (misspelt, or not supported by this plugin)");
}

std::vector<std::pair<std::string, SourceLocation>> Properties::unused() const {
    std::vector<std::pair<std::string, SourceLocation>> out;
    for (const auto& [name, entry] : values_)
        if (!entry.used) out.emplace_back(name, entry.where);
    return out;
}

void Properties::mark_all_used() const {
    for (const auto& [name, entry] : values_) entry.used = true;
}

const std::string* Properties::peek_string(const std::string& name) const {
    auto it = values_.find(name);
    return it == values_.end() ? nullptr : std::get_if<std::string>(&it->second.value);
}

void Properties::replace_string(const std::string& name, std::string value) {
    auto it = values_.find(name);
    if (it == values_.end() || !std::holds_alternative<std::string>(it->second.value))
        throw SceneError(
            where_, class_ + " \"" + type_ + "\": no string parameter \"" + name + "\" to replace");
    it->second.value = std::move(value);
}

}  // namespace render
