#include "core/materials/hair.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

using warp::safe_sqrt;

constexpr float k2Pi = 2.0f * kPi;
constexpr float kLn2 = 0.693147181f;

float sqr(float x) {
    return x * x;
}

float safe_asin(float x) {
    return std::asin(std::clamp(x, -1.0f, 1.0f));
}

// Modified Bessel function of the first kind, order 0, by its power series, summed until the
// terms no longer matter (pbrt-v4 stops at ten terms, 2 % short at x = 12).
float bessel_i0(float x) {
    double sum = 0, term = 1;  // term_i = (x^2 / 4)^i / (i!)^2
    const double q = double(x) * x / 4;
    for (int i = 0; i < 64 && term > 1e-9 * sum; ++i) {
        sum += term;
        term *= q / double((i + 1) * (i + 1));
    }
    return float(sum);
}

// log I0(x); the asymptotic expansion where I0 would overflow or lose precision.
float log_bessel_i0(float x) {
    if (x > 12) return x + 0.5f * (-std::log(k2Pi) + std::log(1 / x) + 1 / (8 * x));
    return std::log(bessel_i0(x));
}

// d'Eon et al. 2011's longitudinal scattering function (normalised over theta_i with measure
// cos theta_i d theta_i); the log form for small variances avoids overflow of I0 and sinh.
float longitudinal(float cos_theta_i, float cos_theta_o, float sin_theta_i, float sin_theta_o,
                   float v) {
    const float a = cos_theta_i * cos_theta_o / v, b = sin_theta_i * sin_theta_o / v;
    if (v <= 0.1f) return std::exp(log_bessel_i0(a) - b - 1 / v + kLn2 + std::log(1 / (2 * v)));
    return std::exp(-b) * bessel_i0(a) / (std::sinh(1 / v) * 2 * v);
}

// Attenuation of each term: Fresnel reflectance f at the entry point, transmittance T of one
// crossing; the last term sums p >= kMaxP as a geometric series.
std::array<Rgb, HairBsdf::kMaxP + 1> attenuation(float cos_theta_o, float eta, float h,
                                                 const Rgb& transmittance) {
    std::array<Rgb, HairBsdf::kMaxP + 1> ap;
    const float cos_gamma_o = safe_sqrt(1 - h * h);
    const float f = fresnel_dielectric(cos_theta_o * cos_gamma_o, eta).reflectance;
    ap[0] = Rgb(f);
    ap[1] = transmittance * sqr(1 - f);
    for (int p = 2; p < HairBsdf::kMaxP; ++p) ap[size_t(p)] = ap[size_t(p - 1)] * transmittance * f;
    // The geometric series of p >= kMaxP; at T f = 1 (a grazing entry, |h| = 1, into a clear
    // fibre) every term past R is 0 and so is their sum.
    for (int c = 0; c < 3; ++c) {
        const float tf = transmittance[c] * f;
        ap[HairBsdf::kMaxP][c] = tf < 1 ? ap[HairBsdf::kMaxP - 1][c] * tf / (1 - tf) : 0.0f;
    }
    return ap;
}

// Net azimuthal deflection of term p.
float azimuth_shift(int p, float gamma_o, float gamma_t) {
    return 2 * float(p) * gamma_t - 2 * gamma_o + float(p) * kPi;
}

float logistic(float x, float s) {
    x = std::abs(x);
    const float e = std::exp(-x / s);
    return e / (s * sqr(1 + e));
}

float logistic_cdf(float x, float s) {
    return 1 / (1 + std::exp(-x / s));
}

// The logistic restricted to [-pi, pi] and renormalised.
float trimmed_logistic(float x, float s) {
    return logistic(x, s) / (logistic_cdf(kPi, s) - logistic_cdf(-kPi, s));
}

float sample_trimmed_logistic(float u, float s) {
    const float lo = logistic_cdf(-kPi, s), hi = logistic_cdf(kPi, s);
    const float x = -s * std::log(1 / (u * (hi - lo) + lo) - 1);
    return std::clamp(x, -kPi, kPi);
}

// Azimuthal scattering of term p at relative azimuth phi.
float azimuthal(float phi, int p, float s, float gamma_o, float gamma_t) {
    float d = phi - azimuth_shift(p, gamma_o, gamma_t);
    // Wrap into [-pi, pi]; the shift is bounded, so a few turns at most.
    d = std::remainder(d, k2Pi);
    return trimmed_logistic(d, s);
}

float cos_of_sin(float s) {
    return safe_sqrt(1 - s * s);
}

}  // namespace

HairBsdf::HairBsdf(const HairParams& params, HairOffset offset)
    : params_(params), offset_(offset), h_(0) {
    const float bm = params_.beta_m, bn = params_.beta_n;
    // Fits of Chiang et al. 2016 (eq. 7, 8): roughness to variance and to logistic scale.
    v_[0] = sqr(0.726f * bm + 0.812f * sqr(bm) + 3.7f * std::pow(bm, 20.0f));
    v_[1] = 0.25f * v_[0];
    v_[2] = 4 * v_[0];
    v_[3] = v_[2];
    constexpr float kSqrtPiOver8 = 0.626657069f;
    s_ = kSqrtPiOver8 * (0.265f * bn + 1.194f * sqr(bn) + 5.372f * std::pow(bn, 22.0f));
    sin_2k_alpha_[0] = std::sin(params_.alpha * kPi / 180);
    cos_2k_alpha_[0] = cos_of_sin(sin_2k_alpha_[0]);
    for (int i = 1; i < kMaxP; ++i) {
        sin_2k_alpha_[size_t(i)] = 2 * cos_2k_alpha_[size_t(i - 1)] * sin_2k_alpha_[size_t(i - 1)];
        cos_2k_alpha_[size_t(i)] =
            sqr(cos_2k_alpha_[size_t(i - 1)]) - sqr(sin_2k_alpha_[size_t(i - 1)]);
    }
}

HairBsdf::HairBsdf(const HairParams& params, float h) : HairBsdf(params, HairOffset::FromHitV) {
    h_ = std::clamp(h, -1.0f, 1.0f);
}

float HairBsdf::h_for(const Vec3& w) const {
    if (offset_ == HairOffset::FromHitV) return h_;
    const float len = std::sqrt(w.y * w.y + w.z * w.z);
    return len > 0 ? std::clamp(-w.y / len, -1.0f, 1.0f) : 0.0f;
}

Rgb HairBsdf::sigma_a_from_concentration(float eumelanin, float pheomelanin) {
    return Rgb(0.419f, 0.697f, 1.37f) * eumelanin + Rgb(0.187f, 0.4f, 1.05f) * pheomelanin;
}

Rgb HairBsdf::sigma_a_from_reflectance(const Rgb& c, float beta_n) {
    const float denominator = 5.969f - 0.215f * beta_n + 2.532f * sqr(beta_n) -
                              10.73f * std::pow(beta_n, 3.0f) + 5.574f * std::pow(beta_n, 4.0f) +
                              0.245f * std::pow(beta_n, 5.0f);
    Rgb sigma_a;
    for (int i = 0; i < 3; ++i) sigma_a[i] = sqr(std::log(c[i]) / denominator);
    return sigma_a;
}

std::shared_ptr<const Bsdf> HairBsdf::create(const Properties& props) {
    HairParams params;
    params.eta = read_ior(props, "int_ior", 1.55f) / read_ior(props, "ext_ior", 1.000277f);
    if (!(std::abs(params.eta - 1) > 1e-6f) || !std::isfinite(params.eta))
        throw props.error("int_ior", "the interior and exterior indices must differ");
    params.beta_m = props.get_float("longitudinal_roughness", 0.3f);
    params.beta_n = props.get_float("azimuthal_roughness", 0.3f);
    params.alpha = props.get_float("scale_tilt", 2.0f);
    for (const char* name : {"longitudinal_roughness", "azimuthal_roughness"}) {
        const float b = props.get_float(name, 0.3f);
        if (!(b >= 0 && b <= 1)) throw props.error(name, "must lie in [0, 1]");
    }
    if (!std::isfinite(params.alpha) || std::abs(params.alpha) > 90)
        throw props.error("scale_tilt", "must be an angle in degrees in [-90, 90]");
    if (props.has("sigma_a") && (props.has("eumelanin") || props.has("pheomelanin")))
        throw props.error("sigma_a", "give sigma_a or the pigment concentrations, not both");
    params.sigma_a = props.has("sigma_a") ? read_reflectance(props, "sigma_a", Rgb(0.0f))
                                          : sigma_a_from_concentration(
                                                read_non_negative(props, "eumelanin", 1.3f),
                                                read_non_negative(props, "pheomelanin", 0.2f));
    params.sigma_a *= read_non_negative(props, "scale", 1.0f);
    return std::make_shared<HairBsdf>(params, HairOffset::FromDirection);
}

HairParams HairTextures::at(Vec2 uv, const HairParams& constant) const {
    HairParams p = constant;
    if (eta) p.eta = std::max(eta->eval_1(uv), 1e-3f);
    if (beta_m) p.beta_m = std::clamp(beta_m->eval_1(uv), 0.0f, 1.0f);
    if (beta_n) p.beta_n = std::clamp(beta_n->eval_1(uv), 0.0f, 1.0f);
    if (alpha) p.alpha = std::clamp(alpha->eval_1(uv), -90.0f, 90.0f);
    switch (absorption) {
        case Absorption::SigmaA:
            if (sigma_a) p.sigma_a = sigma_a->eval(uv);
            break;
        case Absorption::Reflectance:
            // Depends on beta_n, so recomputed when either varies.
            if (reflectance || beta_n) {
                const Rgb c = reflectance ? reflectance->eval(uv) : reflectance_value;
                p.sigma_a = HairBsdf::sigma_a_from_reflectance(
                    Rgb(std::clamp(c.r, 1e-4f, 1.0f), std::clamp(c.g, 1e-4f, 1.0f),
                        std::clamp(c.b, 1e-4f, 1.0f)),
                    p.beta_n);
            }
            break;
        case Absorption::Melanin:
            if (eumelanin || pheomelanin)
                p.sigma_a = HairBsdf::sigma_a_from_concentration(
                    std::max(0.0f, eumelanin ? eumelanin->eval_1(uv) : eumelanin_value),
                    std::max(0.0f, pheomelanin ? pheomelanin->eval_1(uv) : pheomelanin_value));
            break;
    }
    p.sigma_a =
        Rgb(std::max(0.0f, p.sigma_a.r), std::max(0.0f, p.sigma_a.g), std::max(0.0f, p.sigma_a.b));
    return p;
}

std::shared_ptr<const Bsdf> HairBsdf::pbrt_material(const HairParams& params,
                                                    const HairTextures& textures) {
    // h comes from the hit (its v), so the material is resolved at every hit like a textured
    // one; evaluated without a hit it is the fibre's centre, with the textures at uv (1/2, 1/2).
    const HairParams centre = textures.any() ? textures.at(Vec2(0.5f, 0.5f), params) : params;
    auto typical = std::make_shared<HairBsdf>(centre, 0.0f);
    const std::string description = typical->to_string();
    if (!textures.any())
        return std::make_shared<TexturedBsdf>(
            [params](Vec2 uv) { return make_bsdf_at<HairBsdf>(&uv, params, -1 + 2 * uv.y); },
            std::move(typical), description);
    return std::make_shared<TexturedBsdf>(
        [params, textures](Vec2 uv) {
            return make_bsdf_at<HairBsdf>(&uv, textures.at(uv, params), -1 + 2 * uv.y);
        },
        std::move(typical), description);
}

HairBsdf::Outgoing HairBsdf::outgoing(const Vec3& wo) const {
    const float h = h_for(wo);
    Outgoing o;
    o.sin_theta = std::clamp(wo.x, -1.0f, 1.0f);
    o.cos_theta = cos_of_sin(o.sin_theta);
    o.phi = std::atan2(wo.z, wo.y);
    o.gamma_o = safe_asin(h);
    const float eta = params_.eta;
    // The refracted ray inside the fibre, in the projected (azimuthal) plane: modified index
    // eta' of Bravais, cos theta_t of the longitudinal refraction.
    const float cos_theta_t = cos_of_sin(o.sin_theta / eta);
    const float etap = safe_sqrt(eta * eta - sqr(o.sin_theta)) / o.cos_theta;
    const float sin_gamma_t = h / etap;
    o.gamma_t = safe_asin(sin_gamma_t);
    const float cos_gamma_t = cos_of_sin(sin_gamma_t);
    const Rgb& sa = params_.sigma_a;
    const float path = 2 * cos_gamma_t / cos_theta_t;  // one crossing, in fibre radii
    const Rgb transmittance(std::exp(-sa.r * path), std::exp(-sa.g * path), std::exp(-sa.b * path));
    o.ap = attenuation(o.cos_theta, eta, h, transmittance);
    float sum = 0;
    for (const Rgb& a : o.ap) sum += a.average();
    for (size_t p = 0; p <= size_t(kMaxP); ++p) o.ap_pdf[p] = sum > 0 ? o.ap[p].average() / sum : 0;
    // Scale tilts: R by -2 alpha, TT by alpha, TRT by 4 alpha (pbrt-v4's signs).
    const float st = o.sin_theta, ct = o.cos_theta;
    o.sin_tilted[0] = st * cos_2k_alpha_[1] - ct * sin_2k_alpha_[1];
    o.cos_tilted[0] = ct * cos_2k_alpha_[1] + st * sin_2k_alpha_[1];
    o.sin_tilted[1] = st * cos_2k_alpha_[0] + ct * sin_2k_alpha_[0];
    o.cos_tilted[1] = ct * cos_2k_alpha_[0] - st * sin_2k_alpha_[0];
    o.sin_tilted[2] = st * cos_2k_alpha_[2] + ct * sin_2k_alpha_[2];
    o.cos_tilted[2] = ct * cos_2k_alpha_[2] - st * sin_2k_alpha_[2];
    // A tilt past the pole flips cos; the longitudinal lobe only needs its magnitude.
    for (float& c : o.cos_tilted) c = std::abs(c);
    return o;
}

Rgb HairBsdf::f_cos(const Vec3& wo, const Vec3& wi) const {
    const Outgoing o = outgoing(wo);
    const float sin_theta_i = std::clamp(wi.x, -1.0f, 1.0f);
    const float cos_theta_i = cos_of_sin(sin_theta_i);
    const float phi = std::atan2(wi.z, wi.y) - o.phi;
    Rgb sum(0.0f);
    for (int p = 0; p < kMaxP; ++p) {
        const size_t i = size_t(p);
        sum += o.ap[i] *
               (longitudinal(cos_theta_i, o.cos_tilted[i], sin_theta_i, o.sin_tilted[i], v_[i]) *
                azimuthal(phi, p, s_, o.gamma_o, o.gamma_t));
    }
    sum += o.ap[kMaxP] *
           (longitudinal(cos_theta_i, o.cos_theta, sin_theta_i, o.sin_theta, v_[kMaxP]) * kInv2Pi);
    return sum;
}

float HairBsdf::density(const Outgoing& o, const Vec3& wi) const {
    const float sin_theta_i = std::clamp(wi.x, -1.0f, 1.0f);
    const float cos_theta_i = cos_of_sin(sin_theta_i);
    const float phi = std::atan2(wi.z, wi.y) - o.phi;
    float pdf = 0;
    for (int p = 0; p < kMaxP; ++p) {
        const size_t i = size_t(p);
        pdf += o.ap_pdf[i] *
               longitudinal(cos_theta_i, o.cos_tilted[i], sin_theta_i, o.sin_tilted[i], v_[i]) *
               azimuthal(phi, p, s_, o.gamma_o, o.gamma_t);
    }
    pdf += o.ap_pdf[kMaxP] *
           longitudinal(cos_theta_i, o.cos_theta, sin_theta_i, o.sin_theta, v_[kMaxP]) * kInv2Pi;
    return pdf;
}

float HairBsdf::density(const Vec3& wo, const Vec3& wi) const {
    return density(outgoing(wo), wi);
}

Rgb HairBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    // Radiance: wi is the light side; Importance: wo is (the adjoint, see the header).
    const bool radiance = mode == TransportMode::Radiance;
    const Vec3& camera_side = radiance ? wo : wi;
    const Vec3& light_side = radiance ? wi : wo;
    if (light_side.z == 0) return Rgb(0.0f);
    return f_cos(camera_side, light_side) / std::abs(light_side.z);
}

BsdfPdf HairBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    return {density(wo, wi), density(wi, wo)};
}

std::optional<BsdfSample> HairBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                           TransportMode mode) const {
    const Outgoing o = outgoing(wo);
    // Pick the term from the attenuations, reusing u_lobe's remainder for the azimuth.
    int p = 0;
    float below = 0;
    while (p < kMaxP && u_lobe >= below + o.ap_pdf[size_t(p)]) below += o.ap_pdf[size_t(p++)];
    if (!(o.ap_pdf[size_t(p)] > 0)) return std::nullopt;
    const float u_azimuth = std::min((u_lobe - below) / o.ap_pdf[size_t(p)], 1.0f - 1e-7f);
    const float sin_o = p < kMaxP ? o.sin_tilted[size_t(p)] : o.sin_theta;
    const float cos_o = p < kMaxP ? o.cos_tilted[size_t(p)] : o.cos_theta;
    const float v = v_[size_t(p)];
    // Longitudinal: d'Eon's lobe is the marginal of a von Mises-Fisher lobe around the
    // mirrored direction (-theta_o), sampled exactly (Jakob 2012's stable form).
    const float cos_theta = 1 + v * std::log(std::max(u.x, 1e-5f) + (1 - u.x) * std::exp(-2 / v));
    const float sin_theta = cos_of_sin(cos_theta);
    const float cos_phi = std::cos(k2Pi * u.y);
    const float sin_theta_i =
        std::clamp(-cos_theta * sin_o + sin_theta * cos_phi * cos_o, -1.0f, 1.0f);
    const float cos_theta_i = cos_of_sin(sin_theta_i);
    // Azimuthal: the term's deflection plus a trimmed logistic; uniform for the remainder.
    const float dphi =
        p < kMaxP ? azimuth_shift(p, o.gamma_o, o.gamma_t) + sample_trimmed_logistic(u_azimuth, s_)
                  : k2Pi * u_azimuth;
    const float phi_i = o.phi + dphi;
    const Vec3 wi(sin_theta_i, cos_theta_i * std::cos(phi_i), cos_theta_i * std::sin(phi_i));
    if (wi.z == 0) return std::nullopt;
    BsdfSample s;
    s.wi = wi;
    s.pdf_w = {density(o, wi), density(wi, wo)};
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = f(wo, wi, mode) * (std::abs(wi.z) / s.pdf_w.forward);
    if (!s.weight.is_finite()) return std::nullopt;
    s.lobe = wo.z * wi.z > 0 ? kLobeGlossyReflection : kLobeGlossyTransmission;
    return s;
}

std::string HairBsdf::to_string() const {
    std::ostringstream out;
    out << "hair(sigma_a " << params_.sigma_a << ", eta " << params_.eta << ", beta_m "
        << params_.beta_m << ", beta_n " << params_.beta_n << ", alpha " << params_.alpha
        << (offset_ == HairOffset::FromHitV ? ", h " + std::to_string(h_) : ", h from direction")
        << ")";
    return out.str();
}

}  // namespace render
