#pragma once

// Small fixed-size vectors. Geometry is float (as Embree is); accumulation happens in double
// elsewhere (image/), so float here costs no accuracy in the final image.

#include <algorithm>
#include <cmath>
#include <ostream>

namespace render {

struct Vec2 {
    float x = 0, y = 0;
    constexpr Vec2() = default;
    constexpr Vec2(float x_, float y_) : x(x_), y(y_) {}
    constexpr float operator[](int i) const { return i == 0 ? x : y; }
    constexpr Vec2 operator+(Vec2 b) const { return {x + b.x, y + b.y}; }
    constexpr Vec2 operator-(Vec2 b) const { return {x - b.x, y - b.y}; }
    constexpr Vec2 operator*(float s) const { return {x * s, y * s}; }
};

struct Vec3 {
    float x = 0, y = 0, z = 0;
    constexpr Vec3() = default;
    constexpr explicit Vec3(float s) : x(s), y(s), z(s) {}
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}

    constexpr float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    constexpr float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3 operator+(const Vec3& b) const { return {x + b.x, y + b.y, z + b.z}; }
    constexpr Vec3 operator-(const Vec3& b) const { return {x - b.x, y - b.y, z - b.z}; }
    constexpr Vec3 operator*(const Vec3& b) const { return {x * b.x, y * b.y, z * b.z}; }
    constexpr Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
    constexpr Vec3 operator/(float s) const { return *this * (1.0f / s); }
    constexpr Vec3& operator+=(const Vec3& b) { return *this = *this + b; }
    constexpr Vec3& operator-=(const Vec3& b) { return *this = *this - b; }
    constexpr Vec3& operator*=(float s) { return *this = *this * s; }
    constexpr bool operator==(const Vec3& b) const { return x == b.x && y == b.y && z == b.z; }
};

constexpr Vec3 operator*(float s, const Vec3& v) {
    return v * s;
}
constexpr float dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline float abs_dot(const Vec3& a, const Vec3& b) {
    return std::abs(dot(a, b));
}
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
constexpr float length_squared(const Vec3& v) {
    return dot(v, v);
}
inline float length(const Vec3& v) {
    return std::sqrt(dot(v, v));
}
inline Vec3 normalize(const Vec3& v) {
    return v / length(v);
}
inline Vec3 min(const Vec3& a, const Vec3& b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 max(const Vec3& a, const Vec3& b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline float max_component(const Vec3& v) {
    return std::max(v.x, std::max(v.y, v.z));
}
inline bool is_finite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
// Mirror direction of w about the normal n (both pointing away from the surface).
inline Vec3 reflect(const Vec3& w, const Vec3& n) {
    return 2.0f * dot(w, n) * n - w;
}

inline std::ostream& operator<<(std::ostream& os, const Vec3& v) {
    return os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
}

// Linear RGB radiance, reflectance or weight.
struct Rgb {
    float r = 0, g = 0, b = 0;
    constexpr Rgb() = default;
    constexpr explicit Rgb(float s) : r(s), g(s), b(s) {}
    constexpr Rgb(float r_, float g_, float b_) : r(r_), g(g_), b(b_) {}

    constexpr float operator[](int i) const { return i == 0 ? r : (i == 1 ? g : b); }
    constexpr float& operator[](int i) { return i == 0 ? r : (i == 1 ? g : b); }
    constexpr Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
    constexpr Rgb operator-(const Rgb& o) const { return {r - o.r, g - o.g, b - o.b}; }
    constexpr Rgb operator*(const Rgb& o) const { return {r * o.r, g * o.g, b * o.b}; }
    constexpr Rgb operator/(const Rgb& o) const { return {r / o.r, g / o.g, b / o.b}; }
    constexpr Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
    constexpr Rgb operator/(float s) const { return *this * (1.0f / s); }
    constexpr Rgb& operator+=(const Rgb& o) { return *this = *this + o; }
    constexpr Rgb& operator*=(const Rgb& o) { return *this = *this * o; }
    constexpr Rgb& operator*=(float s) { return *this = *this * s; }
    constexpr bool operator==(const Rgb& o) const { return r == o.r && g == o.g && b == o.b; }

    constexpr bool is_black() const { return r == 0 && g == 0 && b == 0; }
    constexpr float max() const { return std::max(r, std::max(g, b)); }
    constexpr float average() const { return (r + g + b) * (1.0f / 3.0f); }
    // Rec. 709 luminance, used for power-proportional light selection and Russian roulette.
    constexpr float luminance() const { return 0.212671f * r + 0.715160f * g + 0.072169f * b; }
    bool is_finite() const { return std::isfinite(r) && std::isfinite(g) && std::isfinite(b); }
};

constexpr Rgb operator*(float s, const Rgb& c) {
    return c * s;
}
inline std::ostream& operator<<(std::ostream& os, const Rgb& c) {
    return os << "[" << c.r << ", " << c.g << ", " << c.b << "]";
}

}  // namespace render
