#include "worker/render_fault.h"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "core/util/arguments.h"

namespace render::service {

RenderFault RenderFault::parse(const std::string& text) {
    const std::string prefix = "throw:";
    if (text.compare(0, prefix.size(), prefix) == 0 && text.size() > prefix.size())
        return {Kind::kThrow, text.substr(prefix.size()), ""};
    if (text == "non-std") return {Kind::kThrowNonStd, "", ""};
    if (text == "abort") return {Kind::kAbort, "", ""};
    throw UsageError("--test-render-fault expects throw:MESSAGE, non-std or abort, got \"" +
                     text.substr(0, 64) + "\"");
}

void RenderFault::raise(const std::string& scene_path) const {
    if (!scene_name.empty() && std::filesystem::path(scene_path).filename() != scene_name) return;
    switch (kind) {
        case Kind::kNone:
            return;
        case Kind::kThrow:
            throw std::runtime_error(message);
        case Kind::kThrowNonStd:
            throw 1;  // an int: not a std::exception
        case Kind::kAbort:
            std::abort();
    }
}

}  // namespace render::service
