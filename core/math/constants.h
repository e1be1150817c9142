#pragma once

#include <limits>

namespace render {

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kInv2Pi = 0.15915494309189533577f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;
inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
// Largest float strictly below 1: keeps u * n inside [0, n) for table look-ups.
inline constexpr float kOneMinusEpsilon = 0x1.fffffep-1f;

}  // namespace render
