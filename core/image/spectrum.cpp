#include "core/image/spectrum.h"

#include <algorithm>
#include <cmath>

namespace render {
namespace {

constexpr double kCieMin = 360, kCieMax = 830;
constexpr int kCieSamples = 95;  // every 5 nm
// Mitsuba's normalisations: a unit spectrum has luminance 1 against the tabulated y curve,
// and so does D65 (scaled by the second constant) as a reflectance's illuminant.
constexpr double kCieYNormalization = 1.0 / 106.7502593994140625;
constexpr double kD65Normalization = 1.0 / 98.99741751876255;

// CIE 1931 2-degree standard observer, 360 to 830 nm in 5 nm steps (CIE 015:2004 table T.4).
constexpr float kCieX[kCieSamples] = {
    0.0001299f,    0.0002321f,    0.0004149f,    0.0007416f,    0.001368f,     0.002236f,
    0.004243f,     0.00765f,      0.01431f,      0.02319f,      0.04351f,      0.07763f,
    0.13438f,      0.21477f,      0.2839f,       0.3285f,       0.34828f,      0.34806f,
    0.3362f,       0.3187f,       0.2908f,       0.2511f,       0.19536f,      0.1421f,
    0.09564f,      0.05795001f,   0.03201f,      0.0147f,       0.0049f,       0.0024f,
    0.0093f,       0.0291f,       0.06327f,      0.1096f,       0.1655f,       0.2257499f,
    0.2904f,       0.3597f,       0.4334499f,    0.5120501f,    0.5945f,       0.6784f,
    0.7621f,       0.8425f,       0.9163f,       0.9786f,       1.0263f,       1.0567f,
    1.0622f,       1.0456f,       1.0026f,       0.9384f,       0.8544499f,    0.7514f,
    0.6424f,       0.5419f,       0.4479f,       0.3608f,       0.2835f,       0.2187f,
    0.1649f,       0.1212f,       0.0874f,       0.0636f,       0.04677f,      0.0329f,
    0.0227f,       0.01584f,      0.01135916f,   0.008110916f,  0.005790346f,  0.004109457f,
    0.002899327f,  0.00204919f,   0.001439971f,  0.0009999493f, 0.0006900786f, 0.0004760213f,
    0.0003323011f, 0.0002348261f, 0.0001661505f, 0.000117413f,  8.307527e-05f, 5.870652e-05f,
    4.150994e-05f, 2.935326e-05f, 2.067383e-05f, 1.455977e-05f, 1.025398e-05f, 7.221456e-06f,
    5.085868e-06f, 3.581652e-06f, 2.522525e-06f, 1.776509e-06f, 1.251141e-06f};
constexpr float kCieY[kCieSamples] = {
    3.917e-06f,  6.965e-06f,  1.239e-05f,  2.202e-05f,  3.9e-05f,    6.4e-05f,    0.00012f,
    0.000217f,   0.000396f,   0.00064f,    0.00121f,    0.00218f,    0.004f,      0.0073f,
    0.0116f,     0.01684f,    0.023f,      0.0298f,     0.038f,      0.048f,      0.06f,
    0.0739f,     0.09098f,    0.1126f,     0.13902f,    0.1693f,     0.20802f,    0.2586f,
    0.323f,      0.4073f,     0.503f,      0.6082f,     0.71f,       0.7932f,     0.862f,
    0.9148501f,  0.954f,      0.9803f,     0.9949501f,  1.0f,        0.995f,      0.9786f,
    0.952f,      0.9154f,     0.87f,       0.8163f,     0.757f,      0.6949f,     0.631f,
    0.5668f,     0.503f,      0.4412f,     0.381f,      0.321f,      0.265f,      0.217f,
    0.175f,      0.1382f,     0.107f,      0.0816f,     0.061f,      0.04458f,    0.032f,
    0.0232f,     0.017f,      0.01192f,    0.00821f,    0.005723f,   0.004102f,   0.002929f,
    0.002091f,   0.001484f,   0.001047f,   0.00074f,    0.00052f,    0.0003611f,  0.0002492f,
    0.0001719f,  0.00012f,    8.48e-05f,   6e-05f,      4.24e-05f,   3e-05f,      2.12e-05f,
    1.499e-05f,  1.06e-05f,   7.4657e-06f, 5.2578e-06f, 3.7029e-06f, 2.6078e-06f, 1.8366e-06f,
    1.2934e-06f, 9.1093e-07f, 6.4153e-07f, 4.5181e-07f};
constexpr float kCieZ[kCieSamples] = {0.0006061f,
                                      0.001086f,
                                      0.001946f,
                                      0.003486f,
                                      0.006450001f,
                                      0.01054999f,
                                      0.02005001f,
                                      0.03621f,
                                      0.06785001f,
                                      0.1102f,
                                      0.2074f,
                                      0.3713f,
                                      0.6456f,
                                      1.0390501f,
                                      1.3856f,
                                      1.62296f,
                                      1.74706f,
                                      1.7826f,
                                      1.77211f,
                                      1.7441f,
                                      1.6692f,
                                      1.5281f,
                                      1.28764f,
                                      1.0419f,
                                      0.8129501f,
                                      0.6162f,
                                      0.46518f,
                                      0.3533f,
                                      0.272f,
                                      0.2123f,
                                      0.1582f,
                                      0.1117f,
                                      0.07824999f,
                                      0.05725001f,
                                      0.04216f,
                                      0.02984f,
                                      0.0203f,
                                      0.0134f,
                                      0.008749999f,
                                      0.005749999f,
                                      0.0039f,
                                      0.002749999f,
                                      0.0021f,
                                      0.0018f,
                                      0.001650001f,
                                      0.0014f,
                                      0.0011f,
                                      0.001f,
                                      0.0008f,
                                      0.0006f,
                                      0.00034f,
                                      0.00024f,
                                      0.00019f,
                                      0.0001f,
                                      4.999999e-05f,
                                      3e-05f,
                                      2e-05f,
                                      1e-05f,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0,
                                      0};
// CIE standard illuminant D65, relative spectral power (100 at 560 nm), 360 to 830 nm in 5 nm
// steps (CIE S 014-2; the 5 nm values interpolated between the 10 nm ones).
constexpr float kD65[kCieSamples] = {
    46.6383f, 49.3637f, 52.0891f, 51.0323f, 49.9755f, 52.3118f, 54.6482f, 68.7015f, 82.7549f,
    87.1204f, 91.486f,  92.4589f, 93.4318f, 90.057f,  86.6823f, 95.7736f, 104.865f, 110.936f,
    117.008f, 117.41f,  117.812f, 116.336f, 114.861f, 115.392f, 115.923f, 112.367f, 108.811f,
    109.082f, 109.354f, 108.578f, 107.802f, 106.296f, 104.79f,  106.239f, 107.689f, 106.047f,
    104.405f, 104.225f, 104.046f, 102.023f, 100.0f,   98.1671f, 96.3342f, 96.0611f, 95.788f,
    92.2368f, 88.6856f, 89.3459f, 90.0062f, 89.8026f, 89.5991f, 88.6489f, 87.6987f, 85.4936f,
    83.2886f, 83.4939f, 83.6992f, 81.863f,  80.0268f, 80.1207f, 80.2146f, 81.2462f, 82.2778f,
    80.281f,  78.2842f, 74.0027f, 69.7213f, 70.6652f, 71.6091f, 72.979f,  74.349f,  67.9765f,
    61.604f,  65.7448f, 69.8856f, 72.4863f, 75.087f,  69.3398f, 63.5927f, 55.0054f, 46.4182f,
    56.6118f, 66.8054f, 65.0941f, 63.3828f, 63.8434f, 64.304f,  61.8779f, 59.4519f, 55.7054f,
    51.959f,  54.6998f, 57.4406f, 58.8765f, 60.3125f};

// Linear interpolation in a 5 nm table; zero outside [360, 830].
double lookup(const float (&table)[kCieSamples], double wavelength) {
    if (!(wavelength >= kCieMin && wavelength <= kCieMax)) return 0;
    const double t = (wavelength - kCieMin) * ((kCieSamples - 1) / (kCieMax - kCieMin));
    const int i = std::clamp(int(t), 0, kCieSamples - 2);
    const double w1 = t - i;
    return (1 - w1) * table[i] + w1 * table[i + 1];
}

}  // namespace

Vec3 cie1931_xyz(double wavelength) {
    return Vec3(float(lookup(kCieX, wavelength)), float(lookup(kCieY, wavelength)),
                float(lookup(kCieZ, wavelength)));
}

double cie_d65(double wavelength) {
    return lookup(kD65, wavelength);
}

Rgb xyz_to_linear_srgb(double x, double y, double z) {
    return Rgb(float(3.240479 * x - 1.537150 * y - 0.498535 * z),
               float(-0.969256 * x + 1.875991 * y + 0.041556 * z),
               float(0.055648 * x - 0.204043 * y + 1.057311 * z));
}

SpectrumToRgb spectrum_to_linear_srgb(const std::vector<double>& wavelengths,
                                      const std::vector<double>& values, bool illuminant,
                                      bool bounded) {
    double x = 0, y = 0, z = 0;
    constexpr int kSteps = 1000;
    const double first = wavelengths.front(), last = wavelengths.back();
    size_t index = 0;
    for (int i = 0; i < kSteps; ++i) {
        const double w = kCieMin + (i / double(kSteps - 1)) * (kCieMax - kCieMin);
        if (w < first || w > last) continue;
        // The interval [wavelengths[index], wavelengths[index + 1]] that holds w.
        while (index + 2 < wavelengths.size() && wavelengths[index + 1] <= w) ++index;
        const double w0 = wavelengths[index], w1 = wavelengths[index + 1];
        const double v0 = values[index] * kCieYNormalization,
                     v1 = values[index + 1] * kCieYNormalization;
        double v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1);
        if (illuminant) v *= lookup(kD65, w) * kD65Normalization;
        x += lookup(kCieX, w) * v;
        y += lookup(kCieY, w) * v;
        z += lookup(kCieZ, w) * v;
    }
    const double scale = (kCieMax - kCieMin) / kSteps;
    SpectrumToRgb out;
    out.rgb = xyz_to_linear_srgb(x * scale, y * scale, z * scale);
    for (int c = 0; c < 3; ++c) {
        const float v = out.rgb[c];
        const float clamped = bounded ? std::clamp(v, 0.0f, 1.0f) : std::max(v, 0.0f);
        if (clamped != v) out.clamped = true;
        out.rgb[c] = clamped;
    }
    return out;
}

}  // namespace render
