#pragma once

// Error messages about a job's files, as its owner wrote them: the server and the workers keep
// a job's bundle in a folder of their own (store or cache), which a message must not show.

#include <string>

namespace render {

// `message` with every occurrence of `folder` + "/" removed, so that paths read as in the
// client's bundle (e.g. "scene.xml:16: ... cannot read checker.png").
inline std::string with_bundle_paths(std::string message, const std::string& folder) {
    const std::string prefix = folder + "/";
    for (size_t at; (at = message.find(prefix)) != std::string::npos;)
        message.erase(at, prefix.size());
    return message;
}

}  // namespace render
