// "An algorithm is its files and one row" (docs/design/architecture.md, "Adding an algorithm"),
// proven: a test algorithm registered here, by its row alone, appears wherever the tables drive —
// the
// --help text, the tables of `render --describe-options` that scripts read, the options check of
// a service request, the memory estimate a worker refuses jobs by, both scene formats'
// integrator names, and rendering itself. A consumer that kept a list of its own (or picked by
// name) instead of reading the row fails one of these. And a row that lacks a required field
// is refused when it is registered, not discovered later as a silent default.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/integrators/integrator.h"
#include "core/render/algorithms.h"
#include "core/render/iteration_memory.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "service/request_options.h"

namespace render {
namespace {

// Each iteration adds max_depth + 0.5 to every pixel: the image shows which settings the
// integrator was made with.
class ConstantImage final : public Integrator {
  public:
    explicit ConstantImage(float value) : value_(value) {}
    void render_iteration(const Scene&, const IterationKey&, AccumulationBuffer& target,
                          TechniqueLayers*, RenderStats&) const override {
        for (size_t p = 0; p < target.pixel_count(); ++p) target.add(p, Rgb(value_));
    }

  private:
    float value_;
};

constexpr uint64_t kTestWorkingMemory = 123456789;

Algorithm test_row() {
    Algorithm row;
    row.name = "test_constant";
    row.aliases = {"test_constant_mitsuba"};
    row.pbrt_integrators = {"testconstant"};
    row.description = "a test's constant image";
    row.options = {"max_depth"};
    row.variants = {{{"max_depth", "3"}}};
    row.create = [](const RenderSettings& s) -> std::unique_ptr<Integrator> {
        return std::make_unique<ConstantImage>(float(s.max_depth) + 0.5f);
    };
    row.iteration_memory = [](const IterationMemoryInput&, IterationMemoryParts& parts) {
        parts.add(kTestWorkingMemory, "the test's buffers");
    };
    row.benchmarks = {"convergence"};
    return row;
}

// The table is the process's: the row is registered once for every test of this file.
const Algorithm& registered() {
    static const Algorithm* row = [] {
        register_algorithm(test_row());
        return find_algorithm("test_constant");
    }();
    return *row;
}

const char* kScene = R"(<scene version="3.0.0">
    <integrator type="test_constant_mitsuba"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="3"/></film>
    </sensor>
    <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>)";

TEST(AlgorithmRow, ATestRowIsInTheHelpText) {
    registered();
    const std::string help = algorithms_help();
    EXPECT_NE(help.find("test_constant, test_constant_mitsuba"), std::string::npos) << help;
    EXPECT_NE(help.find("a test's constant image"), std::string::npos) << help;
    EXPECT_NE(algorithm_names().find("test_constant"), std::string::npos);
}

TEST(AlgorithmRow, ATestRowIsInTheTablesScriptsRead) {
    registered();
    const nlohmann::json tables = nlohmann::json::parse(render_tables_json());
    const nlohmann::json* row = nullptr;
    for (const nlohmann::json& a : tables["algorithms"])
        if (a["name"] == "test_constant") row = &a;
    ASSERT_NE(row, nullptr);
    EXPECT_EQ((*row)["description"], "a test's constant image");
    EXPECT_EQ((*row)["aliases"], nlohmann::json({"test_constant_mitsuba"}));
    EXPECT_EQ((*row)["pbrt_integrators"], nlohmann::json({"testconstant"}));
    EXPECT_EQ((*row)["benchmarks"], nlohmann::json({"convergence"}));
    EXPECT_EQ((*row)["variants"], nlohmann::json::array({{{"max_depth", "3"}}}));
    // Its option, and the options every algorithm reads.
    const auto& options = (*row)["options"];
    EXPECT_NE(std::find(options.begin(), options.end(), "max_depth"), options.end());
    EXPECT_NE(std::find(options.begin(), options.end(), "seed"), options.end());
    EXPECT_EQ(std::find(options.begin(), options.end(), "radius_factor"), options.end());
    // And the option's side of the same table.
    for (const nlohmann::json& o : tables["options"]) {
        const auto& read_by = o["read_by"];
        const bool reads =
            std::find(read_by.begin(), read_by.end(), "test_constant") != read_by.end();
        if (o["name"] == "max_depth") EXPECT_TRUE(reads);
        if (o["name"] == "radius_factor") EXPECT_FALSE(reads);
    }
}

TEST(AlgorithmRow, AServiceRequestForATestRowIsCheckedByItsOptions) {
    registered();
    const SceneSettings scene;
    // A request's options pass the service's check, then resolve against the row.
    const OptionMap ok = {{"max_depth", "3"}};
    EXPECT_EQ(service::check_request_options(ok), "");
    EXPECT_EQ(resolve_render_settings("test_constant", ok, scene).max_depth, 3);
    // An option it does not read is refused, naming the algorithms that do.
    try {
        resolve_render_settings("test_constant", {{"radius_factor", "0.01"}}, scene);
        ADD_FAILURE() << "an option the test row does not read was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("radius_factor"), std::string::npos) << e.what();
    }
}

TEST(AlgorithmRow, ATestRowsWorkingMemoryIsInTheEstimate) {
    registered();
    RenderSettings s;
    s.algorithm = "test_constant_mitsuba";  // an alias finds the row too
    RenderSettings pt = s;
    pt.algorithm = "pt";  // keeps nothing per iteration: the per-thread buffers alone
    const IterationMemoryEstimate e = estimate_iteration_memory(s, 64, 64, 1);
    EXPECT_EQ(e.bytes, estimate_iteration_memory(pt, 64, 64, 1).bytes + kTestWorkingMemory);
    EXPECT_NE(e.what.find("test_constant's working memory"), std::string::npos) << e.what;
    EXPECT_NE(e.what.find("the test's buffers"), std::string::npos) << e.what;
}

TEST(AlgorithmRow, BothSceneFormatsNameATestRowByItsIntegrator) {
    registered();
    // Mitsuba: <integrator type="..."> is an alias of the row.
    const std::unique_ptr<Scene> mitsuba = load_scene_from_string(kScene, ".");
    EXPECT_EQ(resolve_render_settings(job_algorithm("", mitsuba->settings.integrator), {},
                                      mitsuba->settings)
                  .algorithm,
              "test_constant");
    // pbrt: Integrator "..." is one of the row's pbrt names.
    const std::unique_ptr<Scene> pbrt = pbrt::load_scene_from_string(
        "Integrator \"testconstant\"\nFilm \"rgb\" \"integer xresolution\" [4] "
        "\"integer yresolution\" [3]\nCamera \"perspective\"\nWorldBegin\n"
        "Shape \"sphere\"\n",
        ".");
    EXPECT_EQ(
        resolve_render_settings(job_algorithm("", pbrt->settings.integrator), {}, pbrt->settings)
            .algorithm,
        "test_constant");
}

TEST(AlgorithmRow, ATestRowRendersThroughTheRenderPath) {
    registered();
    const std::unique_ptr<Scene> scene = load_scene_from_string(kScene, ".");
    // The scene's integrator and its max_depth (4), as a worker resolves a job without --algo.
    const RenderSettings s =
        resolve_render_settings(job_algorithm("", scene->settings.integrator), {}, scene->settings);
    EXPECT_NO_THROW(check_algorithm_supports_scene(s, *scene));
    const IterationResult r = render_iterations(*scene, s, 0, IterationRange{1, 3});
    ASSERT_EQ(r.count, 2u);
    for (double v : r.sum.values()) EXPECT_EQ(v, 2 * 4.5);
}

TEST(AlgorithmRow, ARowLackingARequiredFieldIsRefused) {
    registered();
    auto refused = [](Algorithm row, const std::string& field) {
        try {
            register_algorithm(std::move(row));
            ADD_FAILURE() << "a row without " << field << " was registered";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
        }
    };
    Algorithm row = test_row();
    row.name = "test_other";
    row.aliases = {};
    Algorithm no_memory = row, no_create = row, no_description = row, no_name = row;
    no_memory.iteration_memory = nullptr;
    no_create.create = nullptr;
    no_description.description = "";
    no_name.name = "";
    refused(no_memory, "iteration_memory");
    refused(no_create, "create");
    refused(no_description, "description");
    refused(no_name, "name");
    // A taken name or alias.
    refused(test_row(), "test_constant");
    Algorithm alias_taken = row;
    alias_taken.aliases = {"path"};
    refused(alias_taken, "path");
    EXPECT_EQ(find_algorithm("test_other"), nullptr);
}

}  // namespace
}  // namespace render
