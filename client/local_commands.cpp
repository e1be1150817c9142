// The commands that need no server: `client bundle` (what submit would upload) and `client
// hash` (the asset store's names of files).

#include <cstdio>
#include <map>

#include "client/bundle.h"
#include "client/commands.h"
#include "core/util/sha256.h"

namespace render::service {

int bundle_command(const std::vector<std::string>& args) {
    std::string scene;
    std::map<std::string, std::string> defines;
    render::ArgumentParser p;
    p.value({"-D"}, "name=value", "",
            [&](const std::string& v) { defines.insert(render::parse_define("-D", v)); });
    p.positional([&](const std::string& v) {
        if (!scene.empty()) throw render::UsageError("bundle: unexpected argument " + v);
        scene = v;
    });
    p.parse(args);
    if (scene.empty()) usage_error("bundle: no scene file given");
    SceneBundleInfo b = collect_bundle(scene, defines);
    std::printf("# root %s, scene %s, integrator %s, sample_count %s\n", b.root.c_str(),
                b.scene_path.c_str(), b.integrator.empty() ? "?" : b.integrator.c_str(),
                b.sample_count ? std::to_string(*b.sample_count).c_str() : "?");
    for (const BundleEntry& e : b.files)
        std::printf("%s %10llu %s\n", e.sha256.c_str(), (unsigned long long)e.size, e.path.c_str());
    return 0;
}

int hash_command(const Arguments& args) {
    if (args.empty()) usage_error("hash: no file given");
    for (const std::string& f : args)
        std::printf("%s  %s\n", render::sha256_file(f).c_str(), f.c_str());
    return 0;
}

}  // namespace render::service
