// Colour parameters of pbrt-v4 files as RGB, and warnings.

#include <algorithm>
#include <cmath>
#include <iostream>

#include "core/scene/pbrt/builders.h"

namespace render::pbrt {

void warn(const SourceLocation& where, const std::string& message) {
    std::cerr << "warning: " << where.to_string() << ": " << message << "\n";
}

std::optional<Rgb> get_rgb(const ParamList& params, const std::string& name) {
    const Param* p = params.find(name);
    if (!p) return std::nullopt;
    Rgb out;
    if (p->type == "rgb") {
        if (p->numbers.size() != 3) throw params.error(name, "an rgb value has 3 numbers");
        out = Rgb(float(p->numbers[0]), float(p->numbers[1]), float(p->numbers[2]));
    } else if (p->type == "float") {
        if (p->numbers.size() != 1) throw params.error(name, "expects one value");
        out = Rgb(float(p->numbers[0]));
    } else if (p->type == "spectrum") {
        // (wavelength, value) pairs: only a constant spectrum has one RGB value without a
        // spectral-to-RGB conversion.
        if (!p->strings.empty())
            throw params.error(name, "named spectra (\"" + p->strings[0] +
                                         "\") are not supported here (give rgb)");
        if (p->numbers.size() < 2 || p->numbers.size() % 2 != 0)
            throw params.error(name, "a spectrum is (wavelength, value) pairs");
        for (size_t i = 3; i < p->numbers.size(); i += 2)
            if (p->numbers[i] != p->numbers[1])
                throw params.error(name,
                                   "spectra that vary with wavelength are not supported "
                                   "yet (give rgb)");
        out = Rgb(float(p->numbers[1]));
    } else {
        throw params.error(name, "expects an rgb colour, not " + p->type);
    }
    for (int c = 0; c < 3; ++c)
        if (!std::isfinite(out[c])) throw params.error(name, "must be finite");
    p->used = true;
    return out;
}

std::optional<Rgb> blackbody_rgb(double kelvin) {
    if (!(kelvin >= 1667 && kelvin <= 25000)) return std::nullopt;
    // The chromaticity of the Planckian locus: Kim et al.'s cubic approximation (2002).
    const double t = kelvin, t2 = t * t, t3 = t2 * t;
    const double x = t <= 4000 ? -0.2661239e9 / t3 - 0.2343589e6 / t2 + 0.8776956e3 / t + 0.179910
                               : -3.0258469e9 / t3 + 2.1070379e6 / t2 + 0.2226347e3 / t + 0.240390;
    const double x2 = x * x, x3 = x2 * x;
    const double y = t <= 2222   ? -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * x - 0.20219683
                     : t <= 4000 ? -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * x - 0.16748867
                                 : 3.0817580 * x3 - 5.87338670 * x2 + 3.75112997 * x - 0.37001483;
    // XYZ with Y = 1 (pbrt's photometric normalisation of the light), to linear sRGB.
    const double X = x / y, Y = 1, Z = (1 - x - y) / y;
    const Rgb rgb(float(3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z),
                  float(-0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z),
                  float(0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z));
    return Rgb(std::max(rgb.r, 0.0f), std::max(rgb.g, 0.0f), std::max(rgb.b, 0.0f));
}

}  // namespace render::pbrt
