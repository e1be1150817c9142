// The algorithm table and the render options table (core/render/): every name, list and
// message is derived from them, every option reads back exactly what was written, and the
// settings resolved from the complete options of any algorithm are the settings themselves.
// Also the shared command-line parser (core/util/arguments.h).

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "core/render/algorithms.h"
#include "core/render/image_metadata.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/scene.h"
#include "core/util/arguments.h"
#include "tests/support/test_scenes.h"

namespace render {
namespace {

// Values that every option must accept, spread over its range; the first differs from the
// default so that a test can tell it was applied.
std::vector<std::string> sample_values(const RenderOption& o) {
    switch (o.type) {
        case OptionType::Choice: {
            std::vector<std::string> v(o.choices.rbegin(), o.choices.rend());
            return v;
        }
        case OptionType::Unsigned:
            return {"12345", "0", "18446744073709551615"};
        case OptionType::Integer:
            return {std::to_string(int64_t(o.min) + 1), std::to_string(int64_t(o.min)),
                    std::to_string(int64_t(o.max))};
        case OptionType::Real:
            return {format_real(o.min + (o.max - o.min) * 0.123456789), format_real(o.max),
                    format_real(o.min + (o.max - o.min) * 1e-9)};
    }
    return {};
}

// Values that every option must refuse.
std::vector<std::string> bad_values(const RenderOption& o) {
    std::vector<std::string> v = {"", "x", "1 2"};
    switch (o.type) {
        case OptionType::Choice:
            v.push_back(o.choices.front() + "x");
            break;
        case OptionType::Unsigned:
            v.insert(v.end(), {"-1", "1.5", "18446744073709551616"});
            break;
        case OptionType::Integer:
            v.insert(v.end(), {std::to_string(int64_t(o.min) - 1),
                               std::to_string(int64_t(o.max) + 1), "1.5"});
            break;
        case OptionType::Real:
            v.insert(v.end(), {"nan", "inf", format_real(o.max * 2 + 1), "-1e300"});
            if (o.min_exclusive) v.push_back(format_real(o.min));
            break;
    }
    return v;
}

const Algorithm& reader_of(const RenderOption& o) {
    for (const Algorithm& a : algorithms())
        if (algorithm_reads(a, o)) return a;
    throw std::logic_error("option " + o.name + " is read by no algorithm");
}

TEST(AlgorithmTable, NamesAndAliasesAreUniqueAndFound) {
    std::set<std::string> seen;
    for (const Algorithm& a : algorithms()) {
        EXPECT_TRUE(seen.insert(a.name).second) << a.name;
        EXPECT_EQ(find_algorithm(a.name), &a);
        for (const std::string& alias : a.aliases) {
            EXPECT_TRUE(seen.insert(alias).second) << alias;
            EXPECT_EQ(find_algorithm(alias), &a) << alias;
        }
        ASSERT_NE(a.create, nullptr) << a.name;
        EXPECT_FALSE(a.description.empty()) << a.name;
        // Every option an algorithm names exists.
        for (const std::string& option : a.options)
            EXPECT_NE(find_render_option(option), nullptr) << a.name << " reads " << option;
    }
    EXPECT_EQ(find_algorithm("path"), find_algorithm("pt"));
    EXPECT_EQ(find_algorithm("volpath"), find_algorithm("volpt"));
    EXPECT_EQ(find_algorithm(""), nullptr);
    EXPECT_EQ(find_algorithm("PT"), nullptr);
}

TEST(AlgorithmTable, MessagesAndHelpListEveryAlgorithm) {
    std::string message;
    try {
        find_algorithm_or_throw("mlt");
    } catch (const std::invalid_argument& e) {
        message = e.what();
    }
    const std::string help = algorithms_help();
    for (const Algorithm& a : algorithms()) {
        EXPECT_NE(message.find(a.name), std::string::npos) << message;
        EXPECT_NE(algorithm_names().find(a.name), std::string::npos);
        EXPECT_NE(help.find(a.name), std::string::npos);
        EXPECT_NE(help.find(a.description), std::string::npos);
    }
    EXPECT_NE(message.find("\"mlt\""), std::string::npos) << message;
}

TEST(AlgorithmTable, JobAlgorithmComesFromAlgoOrTheScenesIntegrator) {
    EXPECT_EQ(job_algorithm("", "path"), "path");  // an alias; resolve_render_settings maps it
    EXPECT_EQ(job_algorithm("vcm", "path"), "vcm");
    EXPECT_EQ(job_algorithm("bpt", "direct"), "bpt");  // --algo wins over any integrator
    try {
        job_algorithm("", "direct");
        ADD_FAILURE() << "no error for a scene integrator that names no algorithm";
    } catch (const std::invalid_argument& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("the scene's integrator \"direct\""), std::string::npos) << message;
        EXPECT_NE(message.find("--algo"), std::string::npos) << message;
        EXPECT_NE(message.find(algorithm_names()), std::string::npos) << message;
    }
}

TEST(AlgorithmTable, EveryAlgorithmRendersAnIteration) {
    auto scene = load_scene_from_string(testing::scaled_box_scene(), ".");
    for (const Algorithm& a : algorithms()) {
        RenderSettings settings = resolve_render_settings(a.name, {}, scene->settings);
        EXPECT_EQ(settings.algorithm, a.name);
        auto integrator = make_integrator(settings);
        ASSERT_NE(integrator, nullptr) << a.name;
        EXPECT_NO_THROW(check_algorithm_supports_scene(a.name, *scene)) << a.name;
    }
}

// A homogeneous and a grid medium: which algorithms may render them comes from the table, and
// the refusal names the algorithms that can.
TEST(AlgorithmTable, MediaSupportComesFromTheTable) {
    const std::string homogeneous = R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>
  </sensor>
  <medium type="homogeneous" id="fog"><rgb name="sigma_t" value="0.5"/><rgb name="albedo" value="0.5"/></medium>
  <shape type="sphere"><float name="radius" value="1"/><point name="center" x="0" y="0" z="5"/>
    <bsdf type="null"/><ref name="interior" id="fog"/></shape>
  <emitter type="point"><point name="position" x="0" y="2" z="5"/><rgb name="intensity" value="1"/></emitter>
</scene>)";
    const std::string grid = R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>
  </sensor>
  <medium type="heterogeneous" id="smoke">
    <volume name="sigma_t" type="constvolume"><float name="value" value="0.5"/></volume>
    <rgb name="albedo" value="0.5"/></medium>
  <shape type="sphere"><float name="radius" value="1"/><point name="center" x="0" y="0" z="5"/>
    <bsdf type="null"/><ref name="interior" id="smoke"/></shape>
  <emitter type="point"><point name="position" x="0" y="2" z="5"/><rgb name="intensity" value="1"/></emitter>
</scene>)";
    auto fog = load_scene_from_string(homogeneous, ".");
    auto smoke = load_scene_from_string(grid, ".");
    for (const Algorithm& a : algorithms()) {
        for (const auto& [scene, supported] : {std::pair{fog.get(), a.support.homogeneous_media},
                                               std::pair{smoke.get(), a.support.grid_media}}) {
            if (supported) {
                EXPECT_NO_THROW(check_algorithm_supports_scene(a.name, *scene)) << a.name;
                continue;
            }
            try {
                check_algorithm_supports_scene(a.name, *scene);
                ADD_FAILURE() << a.name << " accepted a medium it does not support";
            } catch (const std::invalid_argument& e) {
                const std::string message = e.what();
                EXPECT_NE(message.find("\"" + a.name + "\""), std::string::npos) << message;
                EXPECT_NE(message.find("volpt"), std::string::npos) << message;
            }
        }
    }
}

TEST(RenderOptions, NamesAndFlagsAreUnique) {
    std::set<std::string> names, flags;
    for (const RenderOption& o : render_options()) {
        EXPECT_TRUE(names.insert(o.name).second) << o.name;
        EXPECT_TRUE(flags.insert(o.flag).second) << o.flag;
        if (!o.negated_flag.empty()) {
            EXPECT_TRUE(flags.insert(o.negated_flag).second);
        }
        EXPECT_EQ(find_render_option(o.name), &o);
        EXPECT_EQ(
            o.flag, "--" +
                        [&] {
                            std::string f = o.name;
                            for (char& c : f)
                                if (c == '_') c = '-';
                            return f;
                        }())
            << "the flag is the name with dashes";
        EXPECT_FALSE(o.help.empty());
        EXPECT_FALSE(o.default_text.empty());
        ASSERT_NE(o.apply, nullptr);
        ASSERT_NE(o.format, nullptr);
        EXPECT_NO_THROW(reader_of(o)) << o.name << " is read by no algorithm";
        for (const auto& [name, value] : o.effective_with) {
            const RenderOption* other = find_render_option(name);
            ASSERT_NE(other, nullptr) << o.name << " needs unknown option " << name;
            EXPECT_NO_THROW(canonical_option_value(*other, value)) << o.name << " needs " << name;
        }
    }
}

// Each accepted value is stored in canonical form, applied to the settings and read back
// unchanged; the first sample value changes the settings (so the option is not ignored).
TEST(RenderOptions, ValuesRoundTripThroughTheSettings) {
    const SceneSettings scene;
    for (const RenderOption& o : render_options()) {
        const Algorithm& a = reader_of(o);
        const std::string default_value =
            render_settings_options(resolve_render_settings(a.name, {}, scene)).at(o.name);
        std::vector<std::string> values = sample_values(o);
        for (size_t i = 0; i < values.size(); ++i) {
            const std::string canonical = canonical_option_value(o, values[i]);
            EXPECT_EQ(canonical_option_value(o, canonical), canonical) << o.name;
            RenderSettings s = resolve_render_settings(a.name, {{o.name, values[i]}}, scene);
            EXPECT_EQ(o.format(s), canonical) << o.name << " = " << values[i];
            if (i == 0) {
                EXPECT_NE(canonical, default_value) << o.name;
            }
        }
    }
}

TEST(RenderOptions, BadValuesAreRefusedNamingTheOption) {
    for (const RenderOption& o : render_options())
        for (const std::string& v : bad_values(o)) {
            try {
                canonical_option_value(o, v);
                ADD_FAILURE() << o.name << " accepted \"" << v << "\"";
            } catch (const std::invalid_argument& e) {
                EXPECT_NE(std::string(e.what()).find(o.name), std::string::npos) << e.what();
            }
        }
}

TEST(RenderOptions, RealsKeepEveryBit) {
    const RenderOption& alpha = *find_render_option("alpha");
    for (double v : {0.1, 1.0 / 3.0, 0.7500000000000001, 1e-300, 0.999999999999})
        EXPECT_EQ(parse_number<double>("alpha", canonical_option_value(alpha, format_real(v))), v);
}

TEST(RenderOptions, UnknownOptionsAndOptionsTheAlgorithmDoesNotReadAreRefused) {
    const SceneSettings scene;
    EXPECT_THROW(resolve_render_settings("pt", {{"radius", "1"}}, scene), std::invalid_argument);
    try {
        resolve_render_settings("pt", {{"radius_factor", "0.01"}}, scene);
        ADD_FAILURE() << "pt accepted radius_factor";
    } catch (const std::invalid_argument& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("radius_factor"), std::string::npos) << message;
        EXPECT_NE(message.find("vcm"), std::string::npos) << "names who reads it: " << message;
    }
    EXPECT_THROW(resolve_render_settings("mlt", {}, scene), std::invalid_argument);
}

TEST(RenderOptions, TheSceneGivesDepthsAndOptionsOverrideThem) {
    SceneSettings scene;
    scene.integrator = "path";
    scene.max_depth = 7;
    scene.rr_depth = 3;
    RenderSettings s = resolve_render_settings("path", {}, scene);
    EXPECT_EQ(s.algorithm, "pt");
    EXPECT_EQ(s.max_depth, 7);
    EXPECT_EQ(s.rr_depth, 3);
    s = resolve_render_settings("pt", {{"max_depth", "2"}}, scene);
    EXPECT_EQ(s.max_depth, 2);
    EXPECT_EQ(s.rr_depth, 3);
}

// The complete options of a job (what the server stores) resolve to the same settings with
// any scene, and the EXR header records exactly those options.
TEST(RenderOptions, CompleteOptionsResolveToTheSameSettingsAndHeader) {
    SceneSettings scene;
    scene.max_depth = 9;
    scene.rr_depth = 2;
    for (const Algorithm& a : algorithms()) {
        OptionMap options;
        for (const RenderOption& o : render_options())
            if (algorithm_reads(a, o)) options[o.name] = sample_values(o).front();
        const RenderSettings s = resolve_render_settings(a.name, options, scene);
        const OptionMap complete = render_settings_options(s);
        const RenderSettings again = resolve_render_settings(a.name, complete, SceneSettings{});
        EXPECT_EQ(render_settings_options(again), complete) << a.name;
        const auto header = image_metadata(s, {"scene.xml", 3, 1.5, 0.25, 0, {{"spp", "4"}}});
        EXPECT_EQ(header.at("render:algorithm"), a.name);
        for (const auto& [name, value] : complete) EXPECT_EQ(header.at("render:" + name), value);
        size_t option_keys = 0;
        for (const auto& [key, value] : header)
            if (find_render_option(key.substr(7)) && key.rfind("render:", 0) == 0) ++option_keys;
        EXPECT_EQ(option_keys, complete.size()) << a.name << ": only the options it reads";
        EXPECT_EQ(header.at("render:define:spp"), "4");
        EXPECT_EQ(header.at("render:iterations"), "3");
    }
}

TEST(RenderOptions, CommandLineFlagsComeFromTheTable) {
    OptionMap options;
    ArgumentParser parser;
    add_render_options(parser, options);
    const std::string help = parser.help();
    for (const RenderOption& o : render_options()) {
        EXPECT_NE(help.find(o.flag), std::string::npos) << o.flag;
        EXPECT_NE(help.find(algorithms_reading(o).substr(0, 10)), std::string::npos)
            << "help names the readers of " << o.name;
    }
    parser.parse({"--mis", "balance", "--alpha", "0.50", "--no-equiangular", "--seed", "3"});
    EXPECT_EQ(
        options,
        (OptionMap{{"alpha", "0.5"}, {"equiangular", "off"}, {"mis", "balance"}, {"seed", "3"}}));
    EXPECT_THROW(parser.parse({"--alpha", "0"}), UsageError);
    EXPECT_THROW(parser.parse({"--mis"}), UsageError);
}

TEST(ArgumentParser, ParsesValuesFlagsAttachedDefinesAndPositionals) {
    std::vector<std::string> seen;
    bool flag = false;
    ArgumentParser p;
    p.value({"--out", "-o"}, "FILE", "output", [&](const std::string& v) { seen.push_back(v); });
    p.value({"-D"}, "k=v", "define", [&](const std::string& v) { seen.push_back("D:" + v); });
    p.flag({"--wait"}, "wait", [&] { flag = true; });
    p.positional([&](const std::string& v) { seen.push_back("pos:" + v); });
    p.parse({"scene.xml", "-o", "a.exr", "-Dspp=4", "-D", "x=1", "--wait"});
    EXPECT_EQ(seen, (std::vector<std::string>{"pos:scene.xml", "a.exr", "D:spp=4", "D:x=1"}));
    EXPECT_TRUE(flag);
    EXPECT_THROW(p.parse({"--outt", "x"}), UsageError);
    EXPECT_THROW(p.parse({"--out"}), UsageError);
    ArgumentParser no_positionals;
    EXPECT_THROW(no_positionals.parse({"scene.xml"}), UsageError);
    EXPECT_NE(p.help().find("--out FILE, -o"), std::string::npos) << p.help();
}

TEST(ArgumentParser, LeadingOptionsStopAtTheCommand) {
    // The client's global options: parsed up to the command, whose arguments are its own.
    std::string server;
    ArgumentParser p;
    p.value({"--server"}, "HOST:PORT", "server", [&](const std::string& v) { server = v; });
    const std::vector<std::string> args = {"--server", "h:1", "fetch", "j", "--out", "x.exr"};
    EXPECT_EQ(p.parse_leading(args), 2u);
    EXPECT_EQ(server, "h:1");
    EXPECT_EQ(p.parse_leading({"--server", "h:2"}), 2u);
    EXPECT_EQ(p.parse_leading({"list", "--server", "h:3"}), 0u);
    EXPECT_EQ(server, "h:2");
    EXPECT_THROW(p.parse_leading({"--bogus", "list"}), UsageError);
    EXPECT_THROW(p.parse_leading({"--server"}), UsageError);
    // help_rows: the layout of help(), for tables that are not options (the client's commands).
    EXPECT_EQ(help_rows({{"  --server HOST:PORT", "server"}}), p.help());
    EXPECT_EQ(help_rows({{"  a-long-command-synopsis X", "text"}}),
              "  a-long-command-synopsis X\n" + std::string(24, ' ') + "text\n");
}

TEST(ArgumentParser, NumbersAreStrict) {
    EXPECT_EQ(parse_number<int>("--n", "42"), 42);
    EXPECT_EQ(parse_number<double>("--x", "1e-3"), 1e-3);
    for (const char* bad : {"", "4x", " 4", "0x10", "1e999"})
        EXPECT_THROW(parse_number<double>("--x", bad), UsageError) << bad;
    EXPECT_THROW(parse_number<int>("--n", "3000000000"), UsageError);
    EXPECT_THROW(parse_number<uint64_t>("--n", "-1"), UsageError);
    EXPECT_EQ(parse_resolution("--r", "64x32", 8192), (std::pair<int, int>{64, 32}));
    EXPECT_THROW(parse_resolution("--r", "8193x1", 8192), UsageError);
    EXPECT_THROW(parse_resolution("--r", "0x1", 8192), UsageError);
    EXPECT_THROW(parse_define("-D", "=1"), UsageError);
    EXPECT_EQ(parse_define("-D", "a=b=c"), (std::pair<std::string, std::string>{"a", "b=c"}));
}

}  // namespace
}  // namespace render
