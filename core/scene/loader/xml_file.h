#pragma once

// One scene file as pugixml parsed it, with what error messages need: its name, the directory
// that relative file names resolve against, line numbers for pugixml's byte offsets, and its
// format version (files older than 2.0.0 are upgraded in place, see version_upgrade.h).

#include <pugixml.hpp>

#include <array>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/base/error.h"

namespace render {

struct FormatVersion {
    std::array<int, 3> v{0, 0, 0};
    bool operator<(const FormatVersion& o) const { return v < o.v; }
    std::string to_string() const;
};

class XmlFile {
  public:
    // Parses `text` (the file's content). Throws SceneError with pugixml's description and the
    // line for malformed XML, and for a root that is not <scene version="x.y.z">.
    XmlFile(std::string text, std::string display_name, std::filesystem::path dir);
    // Reads and parses a file; a missing file is an error naming the path.
    static std::unique_ptr<XmlFile> load(const std::filesystem::path& path);

    pugi::xml_node scene() const { return scene_; }
    FormatVersion version() const { return version_; }
    const std::string& name() const { return name_; }
    const std::filesystem::path& dir() const { return dir_; }
    SourceLocation where(pugi::xml_node node) const;
    SourceLocation where_offset(ptrdiff_t offset) const;

  private:
    std::string name_;
    std::filesystem::path dir_;
    std::vector<size_t> line_starts_;
    pugi::xml_document doc_;
    pugi::xml_node scene_;
    FormatVersion version_;
};

}  // namespace render
