#pragma once

// Algorithm lists for parameterised tests, taken from the algorithm table
// (core/render/algorithms.cpp): a new physically based algorithm joins the furnace and
// iteration-contract tests without editing them.

#include <string>
#include <vector>

#include "core/render/algorithms.h"

namespace render::testing {

// Every algorithm that converges to the scene's image (all but debug shading), in table order.
inline std::vector<std::string> physically_based_algorithms() {
    std::vector<std::string> names;
    for (const Algorithm& a : algorithms())
        if (a.physically_based) names.push_back(a.name);
    return names;
}

}  // namespace render::testing
