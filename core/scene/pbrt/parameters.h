#pragma once

// A pbrt-v4 parameter list: `"float fov" [ 45 ]`, `"rgb L" [ 1 2 3 ]`, `"string type" "x"`
// (a single value may go without brackets). Each value remembers its line and whether it was
// read, so that an unknown or misspelt parameter is an error at its own line, as in the Mitsuba
// loader.

#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/math/vec.h"
#include "core/scene/pbrt/tokenizer.h"

namespace render::pbrt {

struct Param {
    std::string type;  // integer, float, point2, vector2, point3, vector3, normal3, normal,
                       // point, vector, rgb, spectrum, blackbody, bool, string, texture
    std::string name;
    std::vector<double> numbers;
    std::vector<std::string> strings;
    std::vector<bool> bools;
    SourceLocation where;
    mutable bool used = false;
};

// A bare number token as a finite float value; `what` names it in the message.
double parse_number(const Token& token, const std::string& what);

class ParamList {
  public:
    // Reads parameters from `tokens` for as long as the next token is a quoted "type name".
    // `context` (e.g. `Shape "sphere"`) is used in messages.
    static ParamList parse(Tokenizer& tokens, const std::string& context);

    const std::string& context() const { return context_; }
    const Param* find(const std::string& name) const;
    bool has(const std::string& name) const { return find(name) != nullptr; }

    // One value, or `def` when absent. Throw SceneError (the parameter's line) for another
    // type or count. get_float accepts an integer.
    double get_float(const std::string& name, double def) const;
    long long get_int(const std::string& name, long long def) const;
    bool get_bool(const std::string& name, bool def) const;
    std::string get_string(const std::string& name, const std::string& def) const;
    Vec3 get_point3(const std::string& name, const Vec3& def) const;
    // The parameter's type (marks nothing read); empty when absent.
    std::string type_of(const std::string& name) const;
    // All values of an array parameter of one of `types`; empty when absent. `arity` numbers
    // make one element: the count must be a multiple of it.
    std::vector<double> get_numbers(const std::string& name,
                                    std::initializer_list<const char*> types, size_t arity) const;
    std::vector<long long> get_ints(const std::string& name) const;

    // An error about parameter `name` at its line (the directive's line when absent).
    SceneError error(const std::string& name, const std::string& message) const;
    // Throws naming the first parameter nobody read.
    void check_all_used() const;
    // The parameters nobody read.
    std::vector<const Param*> unused() const;

    SourceLocation where;  // of the directive

  private:
    const Param& need(const std::string& name, std::initializer_list<const char*> types,
                      size_t count) const;

    std::string context_;
    std::vector<Param> params_;
};

}  // namespace render::pbrt
