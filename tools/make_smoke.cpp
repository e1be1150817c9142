// `make_smoke`: writes the procedural smoke plume of scenes/smoke/ as a density grid.
//
//   make_smoke [--resolution N] [--seed S] --out FILE.vol|FILE.vdb [--out ...]
//              [--emission FILE.vol [--emission-scale K]]
//
// The density is a rising column: a smooth envelope (a plume that widens and sways with
// height, fading in above the floor and out below the top) times a few octaves of value noise,
// exactly zero on the grid's border voxels, normalised to a maximum of 1. Everything follows
// from (resolution, seed): the same arguments write the same bytes. The grid fills the unit
// cube (the .vol bounding box is [0,1]^3; y is up).
//
// --emission writes a flame's emitted radiance on the same grid (RGB .vol, the `radiance`
// volume of a heterogeneous medium, docs/design/media.md "Emission in media"): a temperature-like
// field, hottest in a core on the plume's axis just above the floor, falling off with the
// distance from the axis and with height, mapped to colour by a fire ramp (dark red, orange,
// yellow-white at the hottest) times K (default 8).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "core/media/vdb_file.h"
#include "core/media/vol_file.h"
#include "core/sampling/rng.h"
#include "core/util/arguments.h"

namespace {

using namespace render;

constexpr const char* kUsage =
    "usage: make_smoke [--resolution N] [--seed S] --out FILE.vol|FILE.vdb [--out ...]\n"
    "  --resolution N   voxels per axis (default 64, 4 to 512)\n"
    "  --seed S         noise seed (default 1)\n"
    "  --out FILE       output file; .vol (Mitsuba) or .vdb (OpenVDB), may repeat\n"
    "  --emission FILE  also write a flame's emitted radiance (RGB .vol)\n"
    "  --emission-scale K  the hottest voxel's red radiance (default 8)\n";

float smoothstep(float a, float b, float x) {
    const float t = std::clamp((x - a) / (b - a), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

// Value noise: hashed lattice values in [-1, 1], quintic interpolation.
struct ValueNoise {
    uint64_t seed;
    float lattice(int x, int y, int z) const {
        uint64_t h = hash_combine(mix64(seed), uint64_t(uint32_t(x)));
        h = hash_combine(h, uint64_t(uint32_t(y)));
        h = hash_combine(h, uint64_t(uint32_t(z)));
        return float(h >> 40) * 0x1p-23f - 1.0f;
    }
    static float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
    float operator()(float x, float y, float z) const {
        const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
        const int ix = int(fx), iy = int(fy), iz = int(fz);
        const float u = fade(x - fx), v = fade(y - fy), w = fade(z - fz);
        auto lerp = [](float a, float b, float t) { return a + (b - a) * t; };
        float c[2][2];
        for (int dz = 0; dz < 2; ++dz)
            for (int dy = 0; dy < 2; ++dy)
                c[dz][dy] =
                    lerp(lattice(ix, iy + dy, iz + dz), lattice(ix + 1, iy + dy, iz + dz), u);
        return lerp(lerp(c[0][0], c[0][1], v), lerp(c[1][0], c[1][1], v), w);
    }
    // Four octaves, result roughly in [-1, 1].
    float fbm(float x, float y, float z) const {
        float sum = 0, amplitude = 0.5f, norm = 0;
        for (int octave = 0; octave < 4; ++octave) {
            const float f = float(1 << octave);
            sum += amplitude * (*this)(x * f + 17.1f * octave, y * f, z * f - 5.3f * octave);
            norm += amplitude;
            amplitude *= 0.5f;
        }
        return sum / norm;
    }
};

float plume_density(const ValueNoise& noise, float x, float y, float z) {
    // Height h = y; the column rises from the floor, sways and widens as it goes.
    const float h = y;
    const float cx = 0.5f + 0.07f * std::sin(5.0f * h + 0.7f) * h;
    const float cz = 0.5f + 0.05f * std::cos(4.0f * h + 1.3f) * h;
    const float radius = 0.07f + 0.27f * h;
    // Turbulence: the noise is advected upwards and stretched horizontally.
    const float n = noise.fbm(4.0f * x, 3.0f * y - 1.5f, 4.0f * z);
    const float d = std::sqrt((x - cx) * (x - cx) + (z - cz) * (z - cz)) *
                    (1.0f + 0.35f * noise.fbm(3.0f * x + 11.0f, 2.0f * y, 3.0f * z + 7.0f));
    const float radial = 1.0f - smoothstep(0.45f * radius, radius, d);
    const float vertical = smoothstep(0.03f, 0.15f, h) * (1.0f - smoothstep(0.72f, 0.95f, h));
    const float detail = std::clamp(0.4f + 1.6f * n, 0.0f, 1.0f);
    // A smooth window that vanishes towards every face of the cube.
    auto window = [](float u) {
        return smoothstep(0.0f, 0.08f, u) * smoothstep(0.0f, 0.08f, 1.0f - u);
    };
    return radial * vertical * detail * window(x) * window(y) * window(z);
}

// Temperature-like field in [0, 1]: a hot core on the plume's axis near the floor, cooling
// with the distance from the axis and with height, with some turbulence.
float flame_temperature(const ValueNoise& noise, float x, float y, float z) {
    const float h = y;
    const float cx = 0.5f + 0.07f * std::sin(5.0f * h + 0.7f) * h;
    const float cz = 0.5f + 0.05f * std::cos(4.0f * h + 1.3f) * h;
    const float d2 = (x - cx) * (x - cx) + (z - cz) * (z - cz);
    const float core = 0.08f + 0.15f * h;  // the hot region narrows less than the plume widens
    const float radial = std::exp(-d2 / (core * core));
    const float vertical = smoothstep(0.02f, 0.1f, h) * (1.0f - smoothstep(0.2f, 0.75f, h));
    const float flicker =
        std::clamp(0.75f + 0.5f * noise.fbm(6.0f * x, 4.0f * y - 3.0f, 6.0f * z), 0.0f, 1.0f);
    return std::clamp(radial * vertical * flicker, 0.0f, 1.0f);
}

// Fire colour ramp: red rises first, then green, then blue (a blackbody's order).
Rgb fire_colour(float temperature) {
    const float t = temperature;
    return Rgb(std::pow(t, 1.5f), std::pow(t, 3.0f), std::pow(t, 6.0f));
}

bool ends_with(const std::string& s, const std::string& suffix) {
    return s.size() >= suffix.size() &&
           s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

int main(int argc, char** argv) {
    int resolution = 64;
    uint64_t seed = 1;
    std::vector<std::string> outputs;
    std::string emission_out;
    float emission_scale = 8.0f;
    bool help = false;
    ArgumentParser parser;
    parser.value({"--resolution"}, "N", "",
                 [&](const std::string& v) { resolution = parse_number<int>("--resolution", v); });
    parser.value({"--seed"}, "S", "",
                 [&](const std::string& v) { seed = parse_number<uint64_t>("--seed", v); });
    parser.value({"--out"}, "FILE", "", [&](const std::string& v) { outputs.push_back(v); });
    parser.value({"--emission"}, "FILE", "", [&](const std::string& v) { emission_out = v; });
    parser.value({"--emission-scale"}, "K", "", [&](const std::string& v) {
        emission_scale = float(parse_number<double>("--emission-scale", v));
    });
    parser.flag({"--help", "-h"}, "", [&] { help = true; });
    try {
        parser.parse(argc, argv);
    } catch (const UsageError& e) {
        std::fprintf(stderr, "make_smoke: %s\n%s", e.what(), kUsage);
        return 2;
    }
    if (help) {
        std::printf("%s", kUsage);
        return 0;
    }
    if (resolution < 4 || resolution > 512) {
        std::fprintf(stderr, "make_smoke: --resolution must be in [4, 512]\n");
        return 2;
    }
    if (outputs.empty()) {
        std::fprintf(stderr, "make_smoke: no --out given\n%s", kUsage);
        return 2;
    }
    for (const std::string& out : outputs)
        if (!ends_with(out, ".vol") && !ends_with(out, ".vdb")) {
            std::fprintf(stderr, "make_smoke: %s: the output must end in .vol or .vdb\n",
                         out.c_str());
            return 2;
        }

    if (!emission_out.empty() && !ends_with(emission_out, ".vol")) {
        std::fprintf(stderr, "make_smoke: %s: the emission output must end in .vol\n",
                     emission_out.c_str());
        return 2;
    }
    if (!(std::isfinite(emission_scale) && emission_scale >= 0)) {
        std::fprintf(stderr, "make_smoke: --emission-scale must be finite and >= 0\n");
        return 2;
    }

    const ValueNoise noise{seed};
    VolumeGridData grid;
    grid.xres = grid.yres = grid.zres = resolution;
    grid.channels = 1;
    grid.bbox.lo = Vec3(0.0f);
    grid.bbox.hi = Vec3(1.0f);
    grid.values.resize(grid.voxel_count());
    float max_value = 0;
    size_t i = 0;
    for (int z = 0; z < resolution; ++z)
        for (int y = 0; y < resolution; ++y)
            for (int x = 0; x < resolution; ++x) {
                const bool border = x == 0 || y == 0 || z == 0 || x == resolution - 1 ||
                                    y == resolution - 1 || z == resolution - 1;
                const float r = float(resolution);
                const float v =
                    border ? 0.0f
                           : plume_density(noise, (x + 0.5f) / r, (y + 0.5f) / r, (z + 0.5f) / r);
                grid.values[i++] = v;
                max_value = std::max(max_value, v);
            }
    double sum = 0;
    size_t nonzero = 0;
    for (float& v : grid.values) {
        if (max_value > 0) v /= max_value;
        sum += v;
        nonzero += v > 0;
    }
    try {
        for (const std::string& out : outputs) {
            if (ends_with(out, ".vol"))
                write_vol_file(out, grid);
            else
                write_vdb_file(out, grid);
            std::printf("make_smoke: wrote %s (%d^3, seed %llu)\n", out.c_str(), resolution,
                        (unsigned long long)seed);
        }
        if (!emission_out.empty()) {
            VolumeGridData emission = grid;
            emission.channels = 3;
            emission.values.assign(emission.voxel_count() * 3, 0.0f);
            const ValueNoise flicker{seed + 1000};
            size_t j = 0;
            for (int z = 0; z < resolution; ++z)
                for (int y = 0; y < resolution; ++y)
                    for (int x = 0; x < resolution; ++x, j += 3) {
                        const float r = float(resolution);
                        const Rgb c =
                            fire_colour(flame_temperature(flicker, (x + 0.5f) / r, (y + 0.5f) / r,
                                                          (z + 0.5f) / r)) *
                            emission_scale;
                        for (int k = 0; k < 3; ++k) emission.values[j + size_t(k)] = c[k];
                    }
            write_vol_file(emission_out, emission);
            std::printf("make_smoke: wrote %s (emitted radiance, RGB, max %g)\n",
                        emission_out.c_str(), double(emission_scale));
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "make_smoke: %s\n", e.what());
        return 1;
    }
    std::printf("make_smoke: mean density %.4f, %.1f %% of the voxels non-zero, max 1\n",
                sum / double(grid.values.size()),
                100.0 * double(nonzero) / double(grid.values.size()));
    return 0;
}
