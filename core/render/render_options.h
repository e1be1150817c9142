#pragma once

// The render options: every setting that, with the scene and the iteration range, determines an
// image, defined once. The `render` command line, the client, the server's validation, the
// worker and the EXR header all read this table (docs/design/architecture.md, "One definition per
// algorithm and per option"):
//   - command-line flags and their help text (add_render_options),
//   - the API's generic `options` map (proto/render.proto), validated against it,
//   - the RenderSettings a worker renders with (resolve_render_settings),
//   - the EXR header attributes render:NAME (render_settings_metadata).
// Which algorithm reads which option is said by the algorithm table (algorithms.h).

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/render/render_settings.h"

namespace render {

class ArgumentParser;
struct SceneSettings;

// Option name -> value text, as on the API and in EXR headers.
using OptionMap = std::map<std::string, std::string>;

enum class OptionType {
    Integer,   // a signed integer in [min, max]
    Unsigned,  // any 64-bit unsigned integer
    Real,      // a finite number in [min, max] (or (min, max] when min_exclusive)
    Choice,    // one of `choices`
};

struct RenderOption {
    std::string name;     // API key and EXR header key (render:NAME)
    std::string flag;     // the command-line flag of `render` and `client submit`
    std::string metavar;  // what the flag's value looks like in --help
    OptionType type = OptionType::Integer;
    std::string help;
    double min = 0, max = 0;
    bool min_exclusive = false;
    std::vector<std::string> choices;
    // Where the default comes from, for --help ("0.003", "the scene's max_depth").
    std::string default_text;
    // Read by every algorithm (seed, layers); otherwise the algorithm table lists its readers.
    bool every_algorithm = false;
    // A flag that sets the option to `negated_value` ("--no-equiangular"), kept for scripts.
    std::string negated_flag, negated_value;
    // Values of other options without which this one has no effect (the clamp schedule needs a
    // clamp): said in --help, and used by the service test to exercise the option.
    std::vector<std::pair<std::string, std::string>> effective_with;
    // Writes a canonical value (canonical_option_value) into the settings, and reads it back.
    void (*apply)(RenderSettings&, const std::string&) = nullptr;
    std::string (*format)(const RenderSettings&) = nullptr;
};

// Every option, in --help order.
const std::vector<RenderOption>& render_options();
// The option of that name, or nullptr.
const RenderOption* find_render_option(std::string_view name);

// "seed, max_depth, ...": every option's name, for error messages.
std::string render_option_names();

// Checks `text` against the option's type and range and returns it in canonical form (numbers
// in their shortest exact text, so that they read back to the same double). Throws
// std::invalid_argument naming the option and what it accepts.
std::string canonical_option_value(const RenderOption& option, const std::string& text);

// The full settings of `algorithm` (a name or alias): the defaults, then the scene's own
// values (max_depth, rr_depth from its integrator), then `options`. Throws
// std::invalid_argument for an unknown algorithm, an unknown option, an option the algorithm
// does not read, or a value out of range; the message names the option.
RenderSettings resolve_render_settings(const std::string& algorithm, const OptionMap& options,
                                       const SceneSettings& scene);

// Every option the settings' algorithm reads, with its value in canonical form: resolving
// these again (with any scene) gives the same settings.
OptionMap render_settings_options(const RenderSettings& settings);

// EXR header attributes of the settings: render:algorithm and render:NAME per option read.
std::map<std::string, std::string> render_settings_metadata(const RenderSettings& settings);

// Declares every option's flag on a command line; given values land in `options` (checked and
// canonical; a bad value is a UsageError).
void add_render_options(ArgumentParser& parser, OptionMap& options);

// Both tables as JSON, for scripts and tests (`render --describe-options`): {"algorithms":
// [{name, aliases, description, homogeneous_media, grid_media, options}], "options": [{name,
// flag, type, help, default, min, max, min_exclusive, choices, negated_flag, every_algorithm,
// read_by}]}.
std::string render_tables_json();

// Shortest decimal text that reads back to exactly `value`.
std::string format_real(double value);

}  // namespace render
