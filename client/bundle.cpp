#include "client/bundle.h"

#include <pugixml.hpp>

#include <algorithm>
#include <set>
#include <stdexcept>
#include <system_error>

#include "core/scene/loader/file_resolver.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/util/sha256.h"

namespace render::service {

namespace fs = std::filesystem;

namespace {

class Collector {
  public:
    Collector(fs::path root, std::map<std::string, std::string> params)
        : root_(root), params_(std::move(params)), resolver_(std::move(root)) {}

    void visit_scene_file(const fs::path& file, int depth) {
        if (depth > 32) throw std::runtime_error(file.string() + ": includes nested too deeply");
        if (!active_.insert(file.string()).second)
            throw std::runtime_error(file.string() + ": include cycle");
        pugi::xml_document doc;
        pugi::xml_parse_result parsed = doc.load_file(file.c_str());
        if (!parsed)
            throw std::runtime_error(file.string() + ": " + parsed.description() +
                                     " (byte offset " + std::to_string(parsed.offset) + ")");
        walk(doc, file, depth);
        active_.erase(file.string());
    }

    void add_file(const fs::path& file, const fs::path& referenced_from) {
        fs::path normal = file.lexically_normal();
        fs::path rel = normal.lexically_relative(root_);
        std::string text = rel.generic_string();
        if (rel.empty() || text == "." || text.rfind("..", 0) == 0 || rel.is_absolute())
            throw std::runtime_error(
                normal.string() + " (referenced from " + referenced_from.string() +
                ") is outside the scene's folder " + root_.string() +
                "; a job can only carry files under the scene's folder: move or copy it there");
        std::error_code ec;
        if (!fs::is_regular_file(normal, ec))
            throw std::runtime_error(normal.string() + " (referenced from " +
                                     referenced_from.string() +
                                     ") does not exist or is not a file");
        if (seen_.insert(text).second) files.push_back({text, normal, "", 0});
    }

    std::vector<BundleEntry> files;
    std::string integrator;
    std::optional<uint64_t> sample_count;

  private:
    // Replaces $name references; nullopt when a name is undefined.
    std::optional<std::string> substitute(const std::string& value, std::string* missing) const {
        std::string out;
        for (size_t i = 0; i < value.size(); ++i) {
            if (value[i] != '$') {
                out += value[i];
                continue;
            }
            size_t j = i + 1;
            while (j < value.size() && (std::isalnum((unsigned char)value[j]) || value[j] == '_'))
                ++j;
            std::string name = value.substr(i + 1, j - i - 1);
            auto it = params_.find(name);
            if (name.empty() || it == params_.end()) {
                if (missing) *missing = name;
                return std::nullopt;
            }
            out += it->second;
            i = j - 1;
        }
        return out;
    }

    std::string need(const std::string& value, const fs::path& file, const pugi::xml_node& node) {
        std::string missing;
        std::optional<std::string> s = substitute(value, &missing);
        if (!s)
            throw std::runtime_error(file.string() + ": <" + node.name() + "> refers to $" +
                                     missing + ", which has no <default> and no -D value");
        return *s;
    }

    void walk(const pugi::xml_node& parent, const fs::path& file, int depth) {
        for (pugi::xml_node node = parent.first_child(); node; node = node.next_sibling()) {
            if (node.type() != pugi::node_element) continue;
            std::string tag = node.name();
            if (tag == "default") {
                std::string name = node.attribute("name").value();
                if (!name.empty() && !params_.count(name)) {
                    std::optional<std::string> v =
                        substitute(node.attribute("value").value(), nullptr);
                    if (v) params_[name] = *v;
                }
            } else if (tag == "path") {
                add_search_path(need(node.attribute("value").value(), file, node), file);
            } else if (tag == "include") {
                std::string name = need(node.attribute("filename").value(), file, node);
                fs::path included = resolve(name, file);
                add_file(included, file);
                visit_scene_file(included, depth + 1);
            } else if (tag == "spectrum" && node.attribute("filename")) {
                // A spectrum file (.spd), resolved as the loader does.
                std::string name = need(node.attribute("filename").value(), file, node);
                add_file(resolve(name, file), file);
            } else if (std::string(node.attribute("name").value()) == "filename" &&
                       node.attribute("value")) {
                std::string name = need(node.attribute("value").value(), file, node);
                add_file(resolve(name, file), file);
            } else if (tag == "integrator" && integrator.empty()) {
                // As the loader: wrappers (moment, aov, ...) are looked through to the first
                // nested integrator.
                pugi::xml_node inner = node;
                while (pugi::xml_node nested = inner.child("integrator")) inner = nested;
                if (auto v = substitute(inner.attribute("type").value(), nullptr)) integrator = *v;
            } else if (tag == "integer" &&
                       std::string(node.attribute("name").value()) == "sample_count" &&
                       std::string(parent.name()) == "sampler" && !sample_count) {
                if (auto v = substitute(node.attribute("value").value(), nullptr)) {
                    try {
                        long long n = std::stoll(*v);
                        if (n > 0) sample_count = uint64_t(n);
                    } catch (const std::exception&) {
                    }
                }
            }
            walk(node, file, depth);
        }
    }

    // The loader's resolution (FileResolver): the naming file's folder, the scene's folder,
    // the <path> folders. A name found nowhere is reported at its first candidate.
    fs::path resolve(const std::string& name, const fs::path& naming_file) const {
        if (std::optional<fs::path> found = resolver_.resolve(name, naming_file.parent_path()))
            return *found;
        return resolver_.candidates(name, naming_file.parent_path()).front();
    }

    // A <path> folder must lie in the scene's folder and be relative: the job's folder on the
    // server and the workers is a copy of the scene's folder, nothing outside it.
    void add_search_path(const std::string& value, const fs::path& file) {
        if (value.empty()) throw std::runtime_error(file.string() + ": <path> has an empty value");
        if (fs::path(value).is_absolute())
            throw std::runtime_error(file.string() + ": <path value=\"" + value +
                                     "\"> is absolute; a job carries only the scene's folder: "
                                     "give the folder relative to the scene's folder");
        fs::path folder = resolver_.search_folder(value);
        std::string rel = folder.lexically_relative(root_).generic_string();
        if (rel.empty() || rel.rfind("..", 0) == 0)
            throw std::runtime_error(file.string() + ": <path value=\"" + value + "\"> (" +
                                     folder.string() + ") is outside the scene's folder " +
                                     root_.string() +
                                     "; a job can only carry files under the scene's folder");
        resolver_.add_search_path(folder);
    }

    fs::path root_;
    std::map<std::string, std::string> params_;
    FileResolver resolver_;
    std::set<std::string> active_, seen_;
};

}  // namespace

void hash_bundle(SceneBundleInfo& bundle) {
    for (BundleEntry& entry : bundle.files) entry.sha256 = sha256_file(entry.absolute, &entry.size);
}

SceneBundleInfo collect_bundle(const fs::path& scene_file,
                               const std::map<std::string, std::string>& defines, bool hash) {
    fs::path scene = fs::absolute(scene_file).lexically_normal();
    std::error_code ec;
    if (!fs::is_regular_file(scene, ec))
        throw std::runtime_error(scene_file.string() + ": no such scene file");
    SceneBundleInfo info;
    info.root = scene.parent_path();
    Collector collector(info.root, defines);
    collector.add_file(scene, scene);
    if (scene.extension() == ".pbrt") {
        // pbrt-v4: Include/Import files and "string filename" parameters, relative to the
        // scene's folder, as the pbrt loader resolves them.
        const pbrt::SceneSummary summary = pbrt::summarize(scene);
        for (const fs::path& file : summary.files) collector.add_file(file, scene);
        collector.integrator = summary.integrator;
        collector.sample_count = uint64_t(std::max(1ll, summary.sample_count));
    } else {
        collector.visit_scene_file(scene, 0);
    }
    info.scene_path = scene.filename().generic_string();
    info.files = std::move(collector.files);
    info.integrator = collector.integrator;
    info.sample_count = collector.sample_count;
    if (hash) hash_bundle(info);
    return info;
}

}  // namespace render::service
