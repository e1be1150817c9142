#include "core/materials/microfacet.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/math/constants.h"

namespace render {
namespace {

constexpr double kInvSqrtPi = 0.56418958354775628695;
constexpr double kTwoOverSqrtPi = 1.12837916709551257390;

Vec3 normal_from_slope(float slope_x, float slope_y) {
    // A facet with slope (dz/dx, dz/dy) has normal (-dz/dx, -dz/dy, 1) up to length.
    return normalize(Vec3(-slope_x, -slope_y, 1.0f));
}

}  // namespace

bool parse_microfacet_type(const std::string& name, MicrofacetType& type) {
    if (name == "beckmann") {
        type = MicrofacetType::Beckmann;
        return true;
    }
    if (name == "ggx") {
        type = MicrofacetType::GGX;
        return true;
    }
    return false;
}

const char* to_string(MicrofacetType type) {
    return type == MicrofacetType::Beckmann ? "beckmann" : "ggx";
}

double erfinv(double y) {
    if (std::isnan(y)) return y;
    const double sign = y < 0 ? -1.0 : 1.0;
    y = std::min(std::abs(y), 1.0 - 1e-16);
    // Starting point: the single-precision polynomials of Giles (2012), "Approximating the
    // erfinv function"; the Newton steps below refine it to double precision.
    double w = -std::log((1.0 - y) * (1.0 + y)), p;
    if (w < 5.0) {
        w -= 2.5;
        p = 2.81022636e-08;
        p = 3.43273939e-07 + p * w;
        p = -3.5233877e-06 + p * w;
        p = -4.39150654e-06 + p * w;
        p = 0.00021858087 + p * w;
        p = -0.00125372503 + p * w;
        p = -0.00417768164 + p * w;
        p = 0.246640727 + p * w;
        p = 1.50140941 + p * w;
    } else {
        w = std::sqrt(w) - 3.0;
        p = -0.000200214257;
        p = 0.000100950558 + p * w;
        p = 0.00134934322 + p * w;
        p = -0.00367342844 + p * w;
        p = 0.00573950773 + p * w;
        p = -0.0076224613 + p * w;
        p = 0.00943887047 + p * w;
        p = 1.00167406 + p * w;
        p = 2.83297682 + p * w;
    }
    double x = p * y;
    // Newton steps to double precision: on erf(x) = y in the body, and in the tail on
    // log(erfc(x)) = log(1 - y), which is nearly quadratic there and keeps relative precision.
    for (int i = 0; i < 8; ++i) {
        const double derivative = kTwoOverSqrtPi * std::exp(-x * x);
        double step;
        if (y > 0.5) {
            const double tail = std::erfc(x);
            if (!(tail > 0) || !(derivative > 0)) break;
            step = (std::log1p(-y) - std::log(tail)) * tail / derivative;
        } else {
            step = (std::erf(x) - y) / derivative;
        }
        x -= step;
        if (std::abs(step) <= 1e-15 * std::abs(x)) break;
    }
    return sign * x;
}

MicrofacetDistribution::MicrofacetDistribution(MicrofacetType type, float alpha_u, float alpha_v,
                                               bool sample_visible)
    : type_(type),
      alpha_u_(std::max(alpha_u, kMinAlpha)),
      alpha_v_(std::max(alpha_v, kMinAlpha)),
      sample_visible_(sample_visible) {}

float MicrofacetDistribution::D(const Vec3& m) const {
    if (m.z <= 0) return 0.0f;
    const float cos2 = m.z * m.z;
    const float x = m.x / alpha_u_, y = m.y / alpha_v_;
    float result;
    if (type_ == MicrofacetType::Beckmann) {
        // exp(-tan^2(theta) (cos^2 phi / au^2 + sin^2 phi / av^2)) / (pi au av cos^4)
        result = std::exp(-(x * x + y * y) / cos2) / (kPi * alpha_u_ * alpha_v_ * cos2 * cos2);
    } else {
        const float t = x * x + y * y + cos2;
        result = 1.0f / (kPi * alpha_u_ * alpha_v_ * t * t);
    }
    return std::isfinite(result) ? result : 0.0f;
}

float MicrofacetDistribution::lambda(const Vec3& w) const {
    // tan^2 of w's angle after stretching the roughness to 1.
    const double xy_alpha2 =
        double(alpha_u_ * w.x) * (alpha_u_ * w.x) + double(alpha_v_ * w.y) * (alpha_v_ * w.y);
    if (xy_alpha2 == 0) return 0.0f;
    if (w.z == 0) return std::numeric_limits<float>::infinity();
    const double tan2_alpha = xy_alpha2 / (double(w.z) * w.z);
    if (type_ == MicrofacetType::GGX) return float(0.5 * (std::sqrt(1.0 + tan2_alpha) - 1.0));
    const double a = 1.0 / std::sqrt(tan2_alpha);
    if (a > 6.0) return 0.0f;  // below 1e-17
    return float(0.5 * (std::exp(-a * a) * kInvSqrtPi / a - std::erfc(a)));
}

float MicrofacetDistribution::G1(const Vec3& w, const Vec3& m) const {
    // A facet seen from its back side cannot be visible.
    if (dot(w, m) * w.z <= 0) return 0.0f;
    return 1.0f / (1.0f + lambda(w));
}

Vec3 MicrofacetDistribution::sample(const Vec3& w, Vec2 u) const {
    u = Vec2(std::min(u.x, kOneMinusEpsilon), std::min(u.y, kOneMinusEpsilon));
    if (!sample_visible_) {
        // D(m) cos(theta_m) is the slope density P22, sampled radially with unit roughness and
        // then stretched: a Gaussian for Beckmann, 1 / (pi (1 + r^2)^2) for GGX.
        const float r = type_ == MicrofacetType::Beckmann ? std::sqrt(-std::log(1.0f - u.x))
                                                          : std::sqrt(u.x / (1.0f - u.x));
        const float phi = 2.0f * kPi * u.y;
        return normal_from_slope(alpha_u_ * r * std::cos(phi), alpha_v_ * r * std::sin(phi));
    }

    // Stretch the view direction to the configuration of unit roughness.
    const Vec3 ws = normalize(Vec3(alpha_u_ * w.x, alpha_v_ * w.y, w.z));

    if (type_ == MicrofacetType::GGX) {
        // Heitz 2018, "Sampling the GGX Distribution of Visible Normals": sample the projected
        // area of the unit hemisphere, seen from ws, and unstretch.
        const float len2 = ws.x * ws.x + ws.y * ws.y;
        const Vec3 t1 = len2 > 0 ? Vec3(-ws.y, ws.x, 0) / std::sqrt(len2) : Vec3(1, 0, 0);
        const Vec3 t2 = cross(ws, t1);
        const float r = std::sqrt(u.x), phi = 2.0f * kPi * u.y;
        const float p1 = r * std::cos(phi);
        const float s = 0.5f * (1.0f + ws.z);
        const float p2 =
            (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * r * std::sin(phi);
        const Vec3 nh =
            t1 * p1 + t2 * p2 + ws * std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2));
        return normalize(Vec3(alpha_u_ * nh.x, alpha_v_ * nh.y, std::max(1e-6f, nh.z)));
    }

    // Beckmann: sample the unit-roughness visible slopes with the view azimuth on +x, rotate
    // to the view azimuth, unstretch.
    const float sin_theta = std::sqrt(ws.x * ws.x + ws.y * ws.y);
    const float cos_phi = sin_theta > 0 ? ws.x / sin_theta : 1.0f;
    const float sin_phi = sin_theta > 0 ? ws.y / sin_theta : 0.0f;
    const Vec2 slope = sample_visible_slope_unit(ws.z, sin_theta, u);
    const float sx = cos_phi * slope.x - sin_phi * slope.y;
    const float sy = sin_phi * slope.x + cos_phi * slope.y;
    return normal_from_slope(alpha_u_ * sx, alpha_v_ * sy);
}

Vec2 MicrofacetDistribution::sample_visible_slope_unit(float cos_theta, float sin_theta,
                                                       Vec2 u) const {
    if (sin_theta < 1e-4f * cos_theta) {
        // Normal incidence: all normals are visible, the slopes are the isotropic Gaussian.
        const float r = std::sqrt(-std::log(1.0f - u.x)), phi = 2.0f * kPi * u.y;
        return {r * std::cos(phi), r * std::sin(phi)};
    }
    // The visible slope x along the view azimuth has density proportional to
    // (1 - x tan(theta)) exp(-x^2) / sqrt(pi) on (-inf, cot(theta)); its CDF is, up to
    // normalisation, 1 + erf(x) + tan(theta) exp(-x^2) / sqrt(pi). We invert it in the
    // variable b = erf(x), which maps the half line to the bounded interval [-1, erf(cot)],
    // with Newton steps safeguarded by bisection (Jakob's improvement of Heitz & d'Eon 2014).
    const double tan_theta = double(sin_theta) / cos_theta;
    const double cot_theta = double(cos_theta) / sin_theta;
    const double target = std::clamp(double(u.x), 1e-9, 1.0 - 1e-9);
    double lo = -1.0, hi = std::erf(cot_theta);
    const double normalization =
        1.0 / (1.0 + hi + kInvSqrtPi * tan_theta * std::exp(-cot_theta * cot_theta));
    double b = lo + target * (hi - lo);
    for (int iteration = 0; iteration < 50; ++iteration) {
        if (!(b > lo && b < hi)) b = 0.5 * (lo + hi);  // also catches NaN
        const double x = erfinv(b);
        const double cdf =
            normalization * (1.0 + b + kInvSqrtPi * tan_theta * std::exp(-x * x)) - target;
        if (std::abs(cdf) < 1e-12) break;
        if (cdf > 0)
            hi = b;
        else
            lo = b;
        const double derivative = normalization * (1.0 - x * tan_theta);  // d cdf / d b
        b -= cdf / derivative;
    }
    // The perpendicular slope is an independent Gaussian of variance 1/2.
    const double y = erfinv(2.0 * std::clamp(double(u.y), 1e-9, 1.0 - 1e-9) - 1.0);
    return {float(erfinv(b)), float(y)};
}

float MicrofacetDistribution::pdf(const Vec3& w, const Vec3& m) const {
    if (!sample_visible_) return D(m) * std::max(0.0f, m.z);
    if (w.z <= 0) return 0.0f;
    // D_w(m) = G1(w, m) max(0, w.m) D(m) / cos(theta_w), Heitz's visible normal density.
    const float result = G1(w, m) * std::max(0.0f, dot(w, m)) * D(m) / w.z;
    return std::isfinite(result) ? result : 0.0f;
}

}  // namespace render
