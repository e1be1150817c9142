// Colour parameters of pbrt-v4 files as RGB, and warnings.

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

}  // namespace render::pbrt
