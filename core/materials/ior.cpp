#include "core/materials/ior.h"

#include <algorithm>
#include <cctype>

namespace render {
namespace {

struct NamedIor {
    const char* name;
    float ior;
};

// Mitsuba's table (which follows refractiveindex.info and standard handbooks).
constexpr NamedIor kDielectrics[] = {
    {"vacuum", 1.0f},      {"helium", 1.000036f},        {"hydrogen", 1.000132f},
    {"air", 1.000277f},    {"carbon dioxide", 1.00045f}, {"water", 1.3330f},
    {"acetone", 1.36f},    {"ethanol", 1.361f},          {"carbon tetrachloride", 1.461f},
    {"glycerol", 1.4729f}, {"benzene", 1.501f},          {"silicone oil", 1.52045f},
    {"bromine", 1.661f},   {"water ice", 1.31f},         {"fused quartz", 1.458f},
    {"pyrex", 1.470f},     {"acrylic glass", 1.49f},     {"polypropylene", 1.49f},
    {"bk7", 1.5046f},      {"sodium chloride", 1.544f},  {"amber", 1.55f},
    {"pet", 1.5750f},      {"diamond", 2.419f},
};

struct NamedConductor {
    const char* name;
    ConductorIor ior;
};

// Spectral measurements (Palik; the data Mitsuba and pbrt ship) reduced to linear sRGB.
constexpr NamedConductor kConductors[] = {
    {"Au", {{0.143119f, 0.374957f, 1.44248f}, {3.98316f, 2.38572f, 1.60322f}}},
    {"Ag", {{0.155265f, 0.116723f, 0.138342f}, {4.82835f, 3.12225f, 2.14696f}}},
    {"Cu", {{0.200438f, 0.924033f, 1.10221f}, {3.91295f, 2.45285f, 2.14219f}}},
    {"Al", {{1.65746f, 0.880369f, 0.521229f}, {9.22387f, 6.26952f, 4.837f}}},
    {"Cr", {{4.36968f, 2.9167f, 1.6547f}, {5.20643f, 4.23136f, 3.75495f}}},
};

std::string to_lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

}  // namespace

std::optional<float> lookup_dielectric_ior(const std::string& name) {
    const std::string key = to_lower(name);
    for (const NamedIor& entry : kDielectrics)
        if (key == entry.name) return entry.ior;
    return std::nullopt;
}

std::vector<std::string> dielectric_ior_names() {
    std::vector<std::string> names;
    for (const NamedIor& entry : kDielectrics) names.emplace_back(entry.name);
    return names;
}

std::optional<ConductorIor> lookup_conductor_ior(const std::string& name) {
    for (const NamedConductor& entry : kConductors)
        if (name == entry.name) return entry.ior;
    return std::nullopt;
}

std::vector<std::string> conductor_names() {
    std::vector<std::string> names;
    for (const NamedConductor& entry : kConductors) names.emplace_back(entry.name);
    return names;
}

}  // namespace render
