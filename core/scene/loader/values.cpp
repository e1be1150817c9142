#include "core/scene/loader/values.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

namespace render {
namespace {

std::string quoted(std::string_view text) {
    std::string s(text.substr(0, 80));
    if (text.size() > 80) s += "...";
    return "\"" + s + "\"";
}

std::string_view trim(std::string_view s) {
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
    return s;
}

}  // namespace

double parse_number(std::string_view text, const SourceLocation& where, const std::string& field) {
    std::string_view s = trim(text);
    const char* first = s.data();
    const char* last = s.data() + s.size();
    if (first != last && *first == '+') ++first;
    double v = 0;
    auto [p, ec] = std::from_chars(first, last, v);
    if (s.empty() || p != last || (ec != std::errc() && ec != std::errc::result_out_of_range))
        throw SceneError(where, field + ": " + quoted(text) + " is not a number");
    if (ec == std::errc::result_out_of_range || !std::isfinite(v) ||
        std::abs(v) > double(std::numeric_limits<float>::max()))
        throw SceneError(where, field + ": " + quoted(text) + " is not a finite number");
    return v;
}

int64_t parse_integer(std::string_view text, const SourceLocation& where,
                      const std::string& field) {
    std::string_view s = trim(text);
    const char* first = s.data();
    const char* last = s.data() + s.size();
    if (first != last && *first == '+') ++first;
    int64_t v = 0;
    auto [p, ec] = std::from_chars(first, last, v);
    if (s.empty() || p != last || ec != std::errc())
        throw SceneError(where, field + ": " + quoted(text) + " is not an integer");
    return v;
}

bool parse_boolean(std::string_view text, const SourceLocation& where, const std::string& field) {
    std::string s(trim(text));
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (s == "true") return true;
    if (s == "false") return false;
    throw SceneError(where, field + ": " + quoted(text) + " is not a boolean (true or false)");
}

std::vector<double> parse_number_list(std::string_view text, const SourceLocation& where,
                                      const std::string& field) {
    std::vector<double> out;
    size_t i = 0;
    auto is_sep = [](char c) { return c == ',' || std::isspace(static_cast<unsigned char>(c)); };
    while (i < text.size()) {
        while (i < text.size() && is_sep(text[i])) ++i;
        size_t start = i;
        while (i < text.size() && !is_sep(text[i])) ++i;
        if (i > start) out.push_back(parse_number(text.substr(start, i - start), where, field));
    }
    return out;
}

}  // namespace render
