#include "core/lights/envmap_light.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>

#include "core/base/error.h"
#include "core/image/exr_io.h"
#include "core/image/srgb.h"
#include "core/lights/scene_disk.h"
#include "core/math/constants.h"

namespace render {
namespace {

float sanitize(float x) {
    return (std::isfinite(x) && x > 0) ? x : 0.0f;
}

}  // namespace

EnvmapLight::EnvmapLight(std::vector<Rgb> texels, int width, int height, const Frame& to_world,
                         std::string name)
    : texels_(std::move(texels)),
      width_(width),
      height_(height),
      to_world_(to_world),
      name_(std::move(name)) {
    if (width_ <= 0 || height_ <= 0 || texels_.size() != size_t(width_) * size_t(height_)) {
        // An empty map is black; keep one texel so that every lookup stays in range.
        texels_.assign(1, Rgb(0.0f));
        width_ = height_ = 1;
    }
    for (Rgb& t : texels_) t = Rgb(sanitize(t.r), sanitize(t.g), sanitize(t.b));

    // Sampling weights luminance * sin(theta), in double and normalised to their maximum so
    // that no row sum overflows a float whatever the dynamic range of the map.
    std::vector<double> weights(texels_.size());
    double max_weight = 0;
    double power[3] = {0, 0, 0};
    for (int row = 0; row < height_; ++row) {
        double theta0 = kPi * double(row) / height_, theta1 = kPi * double(row + 1) / height_;
        double sin_theta = std::sin(kPi * (row + 0.5) / height_);
        // Solid angle of one texel of this row.
        double texel_solid_angle = 2.0 * kPi / width_ * (std::cos(theta0) - std::cos(theta1));
        for (int col = 0; col < width_; ++col) {
            const Rgb& t = texels_[size_t(row) * width_ + col];
            double lum = 0.212671 * t.r + 0.715160 * t.g + 0.072169 * t.b;
            double w = lum * sin_theta;
            weights[size_t(row) * width_ + col] = w;
            max_weight = std::max(max_weight, w);
            for (int c = 0; c < 3; ++c) power[c] += double(t[c]) * texel_solid_angle;
        }
    }
    std::vector<float> normalised(weights.size(), 0.0f);
    if (max_weight > 0)
        for (size_t i = 0; i < weights.size(); ++i) normalised[i] = float(weights[i] / max_weight);
    distribution_ = Distribution2D(normalised, size_t(width_), size_t(height_));
    for (int c = 0; c < 3; ++c)
        radiance_integral_[c] =
            float(std::min(power[c], double(std::numeric_limits<float>::max())));
}

std::unique_ptr<EnvmapLight> EnvmapLight::load(const std::filesystem::path& filename, float scale,
                                               const Frame& to_world) {
    const std::string path = filename.string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(filename, ec))
        throw SceneError("environment map file \"" + path + "\" not found");
    ImageFileData file;
    try {
        file = read_image_file(filename);
    } catch (const ImageFileError& e) {
        throw SceneError("cannot read environment map \"" + path + "\": " + e.reason());
    }
    const int width = file.width, height = file.height, channels = file.channels;
    const std::vector<float>& pixels = file.pixels;

    // Integer formats (PNG, JPEG) store display-encoded values; light needs linear ones.
    const bool decode_srgb = is_srgb_encoded(file.integer_format, file.color_space);

    std::vector<Rgb> texels(size_t(width) * size_t(height));
    for (size_t i = 0; i < texels.size(); ++i) {
        const float* p = &pixels[i * size_t(channels)];
        Rgb c = channels >= 3 ? Rgb(p[0], p[1], p[2]) : Rgb(p[0]);
        if (decode_srgb) c = Rgb(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
        texels[i] = c * scale;
    }
    return std::make_unique<EnvmapLight>(std::move(texels), width, height, to_world, path);
}

std::optional<Frame> EnvmapLight::rotation_frame(const Transform& to_world) {
    Vec3 axes[3] = {to_world.apply_vector(Vec3(1, 0, 0)), to_world.apply_vector(Vec3(0, 1, 0)),
                    to_world.apply_vector(Vec3(0, 0, 1))};
    float len = length(axes[0]);
    if (!(len > 0) || !std::isfinite(len)) return std::nullopt;
    const float tolerance = 1e-3f;
    for (int i = 0; i < 3; ++i) {
        if (std::abs(length(axes[i]) - len) > tolerance * len) return std::nullopt;
        for (int j = i + 1; j < 3; ++j)
            if (std::abs(dot(axes[i], axes[j])) > tolerance * len * len) return std::nullopt;
    }
    return Frame(normalize(axes[0]), normalize(axes[1]), normalize(axes[2]));
}

Vec2 EnvmapLight::direction_to_uv(const Vec3& d) {
    float u = std::atan2(d.x, -d.z) * kInv2Pi;
    u -= std::floor(u);
    if (!(u < 1.0f)) u = 0.0f;  // -tiny + 1 rounds to 1: that is the seam, u = 0
    float v = std::acos(std::clamp(d.y, -1.0f, 1.0f)) * kInvPi;
    return {u, std::clamp(v, 0.0f, kOneMinusEpsilon)};
}

Vec3 EnvmapLight::uv_to_direction(Vec2 uv) {
    float theta = uv.y * kPi, phi = uv.x * (2.0f * kPi);
    float sin_theta = std::sin(theta);
    return {std::sin(phi) * sin_theta, std::cos(theta), -std::cos(phi) * sin_theta};
}

EnvmapLight::Lookup EnvmapLight::lookup(const Vec3& wi) const {
    Vec3 d = to_world_.to_local(wi);
    float len = length(d);
    if (!(len > 0) || !std::isfinite(len)) return {};
    d = d / len;
    Vec2 uv = direction_to_uv(d);
    int col = std::min(int(uv.x * float(width_)), width_ - 1);
    int row = std::min(int(uv.y * float(height_)), height_ - 1);
    Lookup result;
    result.radiance = texels_[size_t(row) * width_ + col];
    // sin(theta) from the direction itself (not from v) so that it vanishes only at the poles.
    float sin_theta = std::sqrt(d.x * d.x + d.z * d.z);
    if (sin_theta > 0) {
        float pdf = distribution_.pdf_a(uv) / (2.0f * kPi * kPi * sin_theta);
        result.pdf_w = std::isfinite(pdf) ? pdf : 0.0f;
    }
    return result;
}

float EnvmapLight::pdf_direction(const Vec3& wi) const {
    return lookup(wi).pdf_w;
}

bool EnvmapLight::sample_direction(Vec2 u, Vec3& wi, Lookup& value) const {
    float pdf_uv;
    Vec2 uv = distribution_.sample(u, &pdf_uv);
    if (!(pdf_uv > 0)) return false;
    wi = normalize(to_world_.to_world(uv_to_direction(uv)));
    // Radiance and density are re-evaluated from the direction, exactly as radiance() does,
    // so that the two always agree (even when rounding moves a sample across a texel edge).
    value = lookup(wi);
    return value.pdf_w > 0 && !value.radiance.is_black() && render::is_finite(wi);
}

bool EnvmapLight::illuminate(const Vec3& /*ref*/, Vec2 u, LightIlluminateSample& out) const {
    Vec3 wi;
    Lookup value;
    if (!sample_direction(u, wi, value)) return false;
    out.wi = wi;
    out.distance = kInfinity;
    out.radiance = value.radiance;
    out.pdf_direct_w = value.pdf_w;
    out.pdf_emission_w = value.pdf_w * scene_disk::pdf_area(scene_sphere_);
    out.cos_at_light = 1.0f;
    return true;
}

bool EnvmapLight::emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const {
    Vec3 wi;
    Lookup value;
    if (!sample_direction(u_direction, wi, value)) return false;
    out.direction = -wi;
    out.origin = scene_disk::sample_origin(scene_sphere_, out.direction, u_position);
    out.energy = value.radiance;
    out.pdf_emission_w = value.pdf_w * scene_disk::pdf_area(scene_sphere_);
    out.pdf_direct_a = value.pdf_w;
    out.cos_at_light = 1.0f;
    return true;
}

LightRadiance EnvmapLight::radiance(const Vec3&, const Vec3&, const Vec3& ray_direction) const {
    Lookup value = lookup(ray_direction);
    LightRadiance r;
    r.radiance = value.radiance;
    r.pdf_direct_a = value.pdf_w;
    r.pdf_emission_w = value.pdf_w * scene_disk::pdf_area(scene_sphere_);
    return r;
}

Rgb EnvmapLight::power() const {
    // In double and clamped: light selection needs a finite number even for absurd maps.
    double area = scene_disk::area(scene_sphere_);
    Rgb p;
    for (int c = 0; c < 3; ++c)
        p[c] = float(std::min(double(radiance_integral_[c]) * area,
                              double(std::numeric_limits<float>::max())));
    return p;
}

std::string EnvmapLight::to_string() const {
    std::ostringstream os;
    os << "EnvmapLight[" << (name_.empty() ? std::string("(in memory)") : "\"" + name_ + "\"")
       << ", " << width_ << " x " << height_ << "]";
    return os.str();
}

}  // namespace render
