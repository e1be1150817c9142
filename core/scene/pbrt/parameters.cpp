#include "core/scene/pbrt/parameters.h"

#include <charconv>
#include <cmath>
#include <set>

namespace render::pbrt {
namespace {

const std::set<std::string> kNumberTypes = {"integer", "float",   "point2",  "vector2",
                                            "point3",  "vector3", "normal3", "normal",
                                            "point",   "vector",  "rgb",     "blackbody"};

}  // namespace

double parse_number(const Token& t, const std::string& param) {
    if (t.quoted) throw SceneError(t.where, "\"" + param + "\": expected a number, got a string");
    double value = 0;
    const char* begin = t.text.data();
    if (!t.text.empty() && t.text[0] == '+') ++begin;
    const char* end = t.text.data() + t.text.size();
    auto [ptr, ec] = std::from_chars(begin, end, value);
    if (ec != std::errc() || ptr != end || begin == end)
        throw SceneError(t.where, "\"" + param + "\": \"" + t.text + "\" is not a number");
    if (!std::isfinite(value) || std::abs(value) > 3.4e38)
        throw SceneError(t.where, "\"" + param + "\": " + t.text + " is not a finite float");
    return value;
}

ParamList ParamList::parse(Tokenizer& tokens, const std::string& context) {
    ParamList list;
    list.context_ = context;
    while (true) {
        const std::optional<Token>& head = tokens.peek();
        if (!head || !head->quoted) break;
        Token decl = *tokens.next();
        const size_t space = decl.text.find_first_of(" \t");
        const size_t name_at = decl.text.find_first_not_of(" \t", space);
        if (space == std::string::npos || name_at == std::string::npos)
            throw SceneError(decl.where, context + ": expected a parameter \"type name\", got \"" +
                                             decl.text + "\"");
        Param p;
        p.type = decl.text.substr(0, space);
        p.name = decl.text.substr(name_at);
        if (p.name.find_first_of(" \t") != std::string::npos)
            throw SceneError(decl.where, context + ": malformed parameter \"" + decl.text + "\"");
        p.where = decl.where;
        const bool numeric = kNumberTypes.count(p.type) != 0;
        const bool is_bool = p.type == "bool";
        const bool is_string = p.type == "string" || p.type == "texture";
        const bool is_spectrum = p.type == "spectrum";
        if (!numeric && !is_bool && !is_string && !is_spectrum)
            throw SceneError(decl.where, context + ": unknown parameter type \"" + p.type +
                                             "\" of \"" + p.name + "\"");
        if (list.find(p.name))
            throw SceneError(decl.where, context + ": parameter \"" + p.name + "\" given twice");
        auto add = [&](const Token& v) {
            if (is_spectrum) {
                if (v.quoted)
                    p.strings.push_back(v.text);
                else
                    p.numbers.push_back(parse_number(v, p.name));
                if (!p.strings.empty() && !p.numbers.empty())
                    throw SceneError(
                        v.where, "\"" + p.name + "\": a spectrum is a name or numbers, not both");
            } else if (numeric) {
                p.numbers.push_back(parse_number(v, p.name));
            } else if (is_bool) {
                // pbrt-v4 writes bools as "true"/"false" (quoted); bare words are accepted too.
                if (v.text == "true")
                    p.bools.push_back(true);
                else if (v.text == "false")
                    p.bools.push_back(false);
                else
                    throw SceneError(v.where, "\"" + p.name + "\": \"" + v.text +
                                                  "\" is not a bool (true or false)");
            } else {
                if (!v.quoted)
                    throw SceneError(v.where,
                                     "\"" + p.name + "\": expected a quoted string, got " + v.text);
                p.strings.push_back(v.text);
            }
        };
        std::optional<Token> v = tokens.next();
        if (!v) throw SceneError(decl.where, context + ": \"" + p.name + "\" has no value");
        if (v->is("[")) {
            while (true) {
                std::optional<Token> item = tokens.next();
                if (!item) throw SceneError(v->where, context + ": \"" + p.name + "\": missing ]");
                if (item->is("]")) break;
                if (item->is("["))
                    throw SceneError(item->where, context + ": \"" + p.name + "\": nested [");
                add(*item);
            }
        } else if (v->is("]")) {
            throw SceneError(v->where, context + ": \"" + p.name + "\": unexpected ]");
        } else {
            add(*v);
        }
        if (p.numbers.empty() && p.strings.empty() && p.bools.empty())
            throw SceneError(decl.where, context + ": \"" + p.name + "\" has no value");
        list.params_.push_back(std::move(p));
    }
    return list;
}

const Param* ParamList::find(const std::string& name) const {
    for (const Param& p : params_)
        if (p.name == name) return &p;
    return nullptr;
}

SceneError ParamList::error(const std::string& name, const std::string& message) const {
    const Param* p = find(name);
    return SceneError(p ? p->where : where, context_ + ": \"" + name + "\": " + message);
}

const Param& ParamList::need(const std::string& name, std::initializer_list<const char*> types,
                             size_t count) const {
    const Param* p = find(name);
    bool ok = false;
    std::string list;
    for (const char* t : types) {
        ok = ok || p->type == t;
        list += (list.empty() ? "" : " or ") + std::string(t);
    }
    if (!ok) throw error(name, "must be of type " + list + ", not " + p->type);
    const size_t n = p->numbers.size() + p->strings.size() + p->bools.size();
    if (count && n != count)
        throw error(name, "expects " + std::to_string(count) + " value" + (count > 1 ? "s" : "") +
                              ", got " + std::to_string(n));
    p->used = true;
    return *p;
}

double ParamList::get_float(const std::string& name, double def) const {
    if (!find(name)) return def;
    return need(name, {"float", "integer"}, 1).numbers[0];
}

long long ParamList::get_int(const std::string& name, long long def) const {
    if (!find(name)) return def;
    const double v = need(name, {"integer"}, 1).numbers[0];
    if (v != std::floor(v) || std::abs(v) > 9.0e15) throw error(name, "is not an integer");
    return static_cast<long long>(v);
}

bool ParamList::get_bool(const std::string& name, bool def) const {
    if (!find(name)) return def;
    return need(name, {"bool"}, 1).bools[0];
}

std::string ParamList::get_string(const std::string& name, const std::string& def) const {
    if (!find(name)) return def;
    return need(name, {"string"}, 1).strings[0];
}

Vec3 ParamList::get_point3(const std::string& name, const Vec3& def) const {
    if (!find(name)) return def;
    const Param& p = need(name, {"point3", "point", "vector3", "vector", "normal", "normal3"}, 3);
    return Vec3(float(p.numbers[0]), float(p.numbers[1]), float(p.numbers[2]));
}

std::string ParamList::type_of(const std::string& name) const {
    const Param* p = find(name);
    return p ? p->type : std::string();
}

std::vector<double> ParamList::get_numbers(const std::string& name,
                                           std::initializer_list<const char*> types,
                                           size_t arity) const {
    if (!find(name)) return {};
    const Param& p = need(name, types, 0);
    if (!p.strings.empty() || !p.bools.empty()) throw error(name, "expects numbers");
    if (arity > 1 && p.numbers.size() % arity != 0)
        throw error(name, "the number of values, " + std::to_string(p.numbers.size()) +
                              ", is not a multiple of " + std::to_string(arity));
    return p.numbers;
}

std::vector<long long> ParamList::get_ints(const std::string& name) const {
    std::vector<long long> out;
    for (double v : get_numbers(name, {"integer"}, 1)) {
        if (v != std::floor(v) || std::abs(v) > 9.0e15) throw error(name, "is not an integer");
        out.push_back(static_cast<long long>(v));
    }
    return out;
}

void ParamList::check_all_used() const {
    for (const Param& p : params_)
        if (!p.used)
            throw SceneError(p.where, context_ + ": parameter \"" + p.type + " " + p.name +
                                          "\" is not supported (unknown or not implemented)");
}

std::vector<const Param*> ParamList::unused() const {
    std::vector<const Param*> out;
    for (const Param& p : params_)
        if (!p.used) out.push_back(&p);
    return out;
}

}  // namespace render::pbrt
