#include "core/util/arguments.h"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <sstream>

namespace render {

void ArgumentParser::value(std::vector<std::string> names, std::string metavar, std::string help,
                           ValueHandler handler) {
    options_.push_back(
        {std::move(names), std::move(metavar), std::move(help), std::move(handler), nullptr});
}

void ArgumentParser::flag(std::vector<std::string> names, std::string help, FlagHandler handler) {
    options_.push_back({std::move(names), "", std::move(help), nullptr, std::move(handler)});
}

const ArgumentParser::Option* ArgumentParser::find(const std::string& arg,
                                                   std::string* attached) const {
    for (const Option& o : options_)
        for (const std::string& name : o.names) {
            if (arg == name) return &o;
            // "-Dname=value": a single-letter option with its value attached.
            if (o.on_value && name.size() == 2 && name[0] == '-' && name[1] != '-' &&
                arg.size() > 2 && arg.compare(0, 2, name) == 0) {
                *attached = arg.substr(2);
                return &o;
            }
        }
    return nullptr;
}

size_t ArgumentParser::parse_options(const std::vector<std::string>& args,
                                     bool stop_at_positional) const {
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        std::string attached;
        const Option* o = a.size() > 1 && a[0] == '-' ? find(a, &attached) : nullptr;
        if (!o) {
            if (a.size() > 1 && a[0] == '-') throw UsageError("unknown option " + a);
            if (stop_at_positional) return i;
            if (!positional_) throw UsageError("unexpected argument \"" + a + "\"");
            positional_(a);
            continue;
        }
        if (o->on_flag) {
            o->on_flag();
        } else if (!attached.empty()) {
            o->on_value(attached);
        } else {
            if (i + 1 >= args.size()) throw UsageError(a + " needs a value");
            o->on_value(args[++i]);
        }
    }
    return args.size();
}

void ArgumentParser::parse(const std::vector<std::string>& args) const {
    parse_options(args, false);
}

size_t ArgumentParser::parse_leading(const std::vector<std::string>& args) const {
    return parse_options(args, true);
}

void ArgumentParser::parse(int argc, char** argv, int first) const {
    parse(std::vector<std::string>(argv + std::min(first, argc), argv + argc));
}

std::string ArgumentParser::help() const {
    std::vector<std::pair<std::string, std::string>> rows;
    for (const Option& o : options_) {
        std::string head = "  " + o.names.front() + (o.metavar.empty() ? "" : " " + o.metavar);
        for (size_t i = 1; i < o.names.size(); ++i) head += ", " + o.names[i];
        rows.emplace_back(std::move(head), o.help);
    }
    return help_rows(rows);
}

std::string help_rows(const std::vector<std::pair<std::string, std::string>>& rows) {
    constexpr size_t kColumn = 24, kWidth = 96;
    std::ostringstream out;
    for (const auto& [head, help] : rows) {
        out << head;
        size_t column = head.size();
        if (column + 2 > kColumn) {
            out << "\n";
            column = 0;
        }
        // Wrap the help text at word boundaries.
        std::istringstream words(help);
        std::string word;
        bool line_start = true;
        size_t used = kColumn;
        out << std::string(kColumn - column, ' ');
        while (words >> word) {
            if (!line_start && used + 1 + word.size() > kWidth) {
                out << "\n" << std::string(kColumn, ' ');
                used = kColumn;
                line_start = true;
            }
            if (!line_start) {
                out << ' ';
                ++used;
            }
            out << word;
            used += word.size();
            line_start = false;
        }
        out << "\n";
    }
    return out.str();
}

template <typename T>
T parse_number(const std::string& what, const std::string& text) {
    T value{};
    const char* begin = text.data();
    const char* end = begin + text.size();
    if (!text.empty() && text[0] == '+') ++begin;
    auto [ptr, ec] = std::from_chars(begin, end, value);
    if (text.empty() || ec != std::errc() || ptr != end)
        throw UsageError(what + " expects " +
                         (std::is_floating_point_v<T> ? "a number" : "an integer") + ", got \"" +
                         text + "\"");
    if constexpr (std::is_floating_point_v<T>)
        if (!std::isfinite(value)) throw UsageError(what + " must be finite, got \"" + text + "\"");
    return value;
}

template int parse_number<int>(const std::string&, const std::string&);
template int64_t parse_number<int64_t>(const std::string&, const std::string&);
template uint32_t parse_number<uint32_t>(const std::string&, const std::string&);
template uint64_t parse_number<uint64_t>(const std::string&, const std::string&);
template double parse_number<double>(const std::string&, const std::string&);

std::pair<int, int> parse_resolution(const std::string& what, const std::string& text,
                                     int max_size) {
    const size_t x = text.find('x');
    if (x == std::string::npos) throw UsageError(what + " expects WxH, got \"" + text + "\"");
    const int width = parse_number<int>(what, text.substr(0, x));
    const int height = parse_number<int>(what, text.substr(x + 1));
    if (width < 1 || height < 1 || width > max_size || height > max_size)
        throw UsageError(what + " must be between 1x1 and " + std::to_string(max_size) + "x" +
                         std::to_string(max_size) + ", got " + text);
    return {width, height};
}

std::pair<std::string, std::string> parse_define(const std::string& what, const std::string& text) {
    const size_t eq = text.find('=');
    if (eq == std::string::npos || eq == 0)
        throw UsageError(what + " expects name=value, got \"" + text + "\"");
    return {text.substr(0, eq), text.substr(eq + 1)};
}

}  // namespace render
