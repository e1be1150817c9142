// The files a pbrt-v4 scene reads, for the client's bundle: Include/Import files (followed)
// and the values of every "string filename" parameter, resolved as the loader resolves them.

#include <cctype>
#include <fstream>
#include <set>
#include <sstream>

#include "core/scene/pbrt/parameters.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/pbrt/tokenizer.h"

namespace render::pbrt {
namespace {

namespace fs = std::filesystem;

void collect(const fs::path& file, const fs::path& scene_dir, int depth,
             std::set<std::string>& active, std::set<std::string>& seen, SceneSummary& summary) {
    std::vector<fs::path>& out = summary.files;
    if (depth > 32) throw SceneError(file.string() + ": includes are nested too deeply");
    if (!active.insert(file.string()).second) throw SceneError(file.string() + ": include cycle");
    std::ifstream in(file, std::ios::binary);
    if (!in) throw SceneError(file.string() + ": cannot read the file");
    std::ostringstream text;
    text << in.rdbuf();
    Tokenizer tokens(text.str(), file.string());
    auto add = [&](const Token& name) {
        fs::path p(name.text);
        if (p.is_relative()) p = scene_dir / p;
        p = p.lexically_normal();
        if (seen.insert(p.string()).second) out.push_back(p);
        return p;
    };
    std::string directive;  // the last one: Film's "filename" is an output, not an input
    bool after_directive = false;
    long long xsamples = 4, ysamples = 4;
    while (std::optional<Token> t = tokens.next()) {
        if (t->is("Include") || t->is("Import")) {
            std::optional<Token> name = tokens.next();
            if (!name || !name->quoted)
                throw SceneError(t->where, t->text + ": expected a quoted file name");
            collect(add(*name), scene_dir, depth + 1, active, seen, summary);
            continue;
        }
        const bool type_token = after_directive && t->quoted;
        after_directive = false;
        if (!t->quoted && !t->text.empty() &&
            std::isupper(static_cast<unsigned char>(t->text[0]))) {
            directive = t->text;
            after_directive = true;
            continue;
        }
        if (type_token) {
            if (directive == "Integrator") summary.integrator = integrator_name(t->text);
            continue;
        }
        if (t->quoted && (directive == "Sampler")) {
            std::istringstream decl(t->text);
            std::string type, name;
            decl >> type >> name;
            if (type == "integer" &&
                (name == "pixelsamples" || name == "xsamples" || name == "ysamples")) {
                std::optional<Token> value = tokens.next();
                if (value && value->is("[")) value = tokens.next();
                if (!value || value->quoted) continue;
                const long long n = static_cast<long long>(parse_number(*value, name));
                if (name == "pixelsamples") summary.sample_count = n;
                if (name == "xsamples") xsamples = n, summary.sample_count = xsamples * ysamples;
                if (name == "ysamples") ysamples = n, summary.sample_count = xsamples * ysamples;
            }
            continue;
        }
        if (t->quoted) {
            std::istringstream decl(t->text);
            std::string type, name, rest;
            decl >> type >> name;
            if (type != "string" || name != "filename" || (decl >> rest) || directive == "Film")
                continue;
            std::optional<Token> value = tokens.next();
            if (value && value->is("[")) value = tokens.next();
            if (!value || !value->quoted)
                throw SceneError(t->where, "\"string filename\": expected a quoted file name");
            if (!value->text.empty()) add(*value);
        }
    }
    active.erase(file.string());
}

}  // namespace

SceneSummary summarize(const fs::path& file) {
    SceneSummary summary;
    summary.integrator = integrator_name("volpath");
    std::set<std::string> active, seen;
    const fs::path scene = fs::absolute(file).lexically_normal();
    collect(scene, scene.parent_path(), 0, active, seen, summary);
    return summary;
}

}  // namespace render::pbrt
