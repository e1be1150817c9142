#pragma once

#include <stdexcept>
#include <string>

namespace render {

// Where a scene-file value came from, for error messages ("file.xml:12: ...").
struct SourceLocation {
    std::string file;
    int line = 0;
    std::string to_string() const { return line > 0 ? file + ":" + std::to_string(line) : file; }
};

// Bad user input (scene file, asset, parameter). Carries a complete, human-readable message
// that names the file, line and field; callers print it and exit non-zero, never crash.
class SceneError : public std::runtime_error {
  public:
    explicit SceneError(const std::string& message) : std::runtime_error(message) {}
    SceneError(const SourceLocation& where, const std::string& message)
        : std::runtime_error(where.to_string() + ": " + message) {}
};

}  // namespace render
