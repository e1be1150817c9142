#pragma once

// Spectra given as wavelength:value lists, turned into the linear sRGB this renderer works in
// exactly as Mitsuba 3's RGB variants turn them (src/core/xml.cpp and spectrum.cpp of
// Mitsuba 3, rewritten; docs/reference/scene-format.md, "Spectra", states the rule):
//   1. values are scaled by 1 / 106.7502593994140625 (Mitsuba's CIE Y normalisation);
//   2. XYZ = (470 / 1000) * sum over 1000 wavelengths w_i = 360 + 470 i / 999 nm inside
//      [first, last wavelength] of xyz(w_i) * s(w_i) * (illuminant ? D65(w_i) : 1), with s
//      linearly interpolated between the given samples and zero outside them, xyz the CIE 1931
//      2-degree matching functions and D65 the CIE illuminant (both tabulated at 5 nm from 360
//      to 830 nm and linearly interpolated), D65 scaled by 1 / 98.99741751876255 (so that
//      a unit reflectance has luminance 1);
//   3. RGB = M XYZ with Mitsuba's XYZ-to-linear-sRGB (Rec. 709, D65 white) matrix;
//   4. clamped to [0, 1] (bounded) or to >= 0 (unbounded), `clamped` telling whether it was.

#include <vector>

#include "core/math/vec.h"

namespace render {

struct SpectrumToRgb {
    Rgb rgb;
    bool clamped = false;  // the colour was outside the range and was clamped (Mitsuba warns)
};

// `wavelengths` (nm) strictly increasing, the same number of finite `values`, at least two.
// `illuminant`: weight by D65 (Mitsuba does for everything but emitted spectra). `bounded`:
// clamp to [0, 1] (reflectances) instead of only to >= 0.
SpectrumToRgb spectrum_to_linear_srgb(const std::vector<double>& wavelengths,
                                      const std::vector<double>& values, bool illuminant,
                                      bool bounded);

// Mitsuba's XYZ to linear sRGB (Rec. 709 primaries, D65 white).
Rgb xyz_to_linear_srgb(double x, double y, double z);

// The CIE 1931 2-degree colour matching functions (x, y, z) and the CIE D65 illuminant
// (relative, 100 at 560 nm), linearly interpolated in their 5 nm tables; zero outside
// [360, 830] nm.
Vec3 cie1931_xyz(double wavelength);
double cie_d65(double wavelength);

}  // namespace render
