#pragma once

// One command-line parser for every executable (render, client, worker, server, make_smoke):
// options are declared with their help text, so the usage text is derived from the same
// declarations that parse. Errors are UsageError exceptions; each program prints them with its
// usage and exits with status 2.

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace render {

struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

class ArgumentParser {
  public:
    using ValueHandler = std::function<void(const std::string&)>;
    using FlagHandler = std::function<void()>;

    // An option that takes the next argument as its value ("--seed 3"). `names` are the
    // spellings ("--iterations", "--spp"); the first one is shown in the help. A single-letter
    // name such as "-D" also accepts the value attached ("-Dname=value").
    void value(std::vector<std::string> names, std::string metavar, std::string help,
               ValueHandler handler);
    // An option without a value ("--wait").
    void flag(std::vector<std::string> names, std::string help, FlagHandler handler);
    // Positional arguments are handed to `handler` in order; without one they are refused.
    void positional(ValueHandler handler) { positional_ = std::move(handler); }

    // Calls the handlers in argument order. "--help"/"-h" is not handled here: declare it as a
    // flag. Throws UsageError for an unknown option or a missing value.
    void parse(const std::vector<std::string>& args) const;
    void parse(int argc, char** argv, int first = 1) const;
    // The options before the first positional argument (a command, whose arguments follow),
    // as parse() does; returns that argument's index (args.size() when there is none).
    size_t parse_leading(const std::vector<std::string>& args) const;

    // "  --name METAVAR    help" lines, aligned, help text wrapped at 96 columns.
    std::string help() const;

  private:
    struct Option {
        std::vector<std::string> names;
        std::string metavar, help;
        ValueHandler on_value;
        FlagHandler on_flag;
    };
    const Option* find(const std::string& arg, std::string* attached) const;
    size_t parse_options(const std::vector<std::string>& args, bool stop_at_positional) const;

    std::vector<Option> options_;
    ValueHandler positional_;
};

// Help lines: each row's head (indented by the caller, e.g. "  --seed N") followed by its text
// aligned at column 24 (on the next line when the head is longer), wrapped at 96 columns.
std::string help_rows(const std::vector<std::pair<std::string, std::string>>& rows);

// Strict number parsing: the whole text must be a number of type T in its range.
// Throws UsageError naming `what` (usually the flag).
template <typename T>
T parse_number(const std::string& what, const std::string& text);

// "WxH" with 1 <= W, H <= max_size.
std::pair<int, int> parse_resolution(const std::string& what, const std::string& text,
                                     int max_size);

// "name=value" with a non-empty name.
std::pair<std::string, std::string> parse_define(const std::string& what, const std::string& text);

}  // namespace render
