#include "core/materials/rough_plastic.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <sstream>
#include <tuple>
#include <vector>

#include "core/materials/bsdf_params.h"
#include "core/materials/fresnel.h"
#include "core/materials/hit_bsdf_storage.h"
#include "core/materials/plastic.h"
#include "core/materials/textured_bsdf.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

// Nodes and weights of the n-point Gauss-Legendre rule on [0, 1] (Newton on P_n).
struct Quadrature {
    std::vector<double> nodes, weights;
};

Quadrature gauss_legendre_unit(int n) {
    Quadrature q;
    q.nodes.resize(size_t(n));
    q.weights.resize(size_t(n));
    for (int i = 0; i < n; ++i) {
        double x = std::cos(kPi * (i + 0.75) / (n + 0.5)), derivative = 1;
        for (int iteration = 0; iteration < 100; ++iteration) {
            double p0 = 1, p1 = x;  // P_0, P_1
            for (int k = 2; k <= n; ++k) {
                const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            derivative = n * (x * p1 - p0) / (x * x - 1);
            const double step = p1 / derivative;
            x -= step;
            if (std::abs(step) < 1e-15) break;
        }
        q.nodes[size_t(i)] = 0.5 * (1 - x);
        q.weights[size_t(i)] = 1.0 / ((1 - x * x) * derivative * derivative);  // (2/..)/2
    }
    return q;
}

// Integral over the visible normals m of a direction with cosine `cos_theta` of
// value(w, m) (the direction w is in the x-z plane), on a Gauss-Legendre grid of the unit
// square mapped to normals. GGX: through its visible-normal sampler (Heitz 2018, closed form
// and smooth), each node weighted 1. Beckmann (whose visible-normal sampler is an iterative
// inversion): through the closed-form sampler of D(m) cos(m), each node weighted by the
// ratio of the visible-normal density G1(w, m) max(0, w.m) D(m) / cos_theta to D(m) cos(m).
template <class Value>
double integrate_visible_normals(const MicrofacetDistribution& distribution, float cos_theta, int n,
                                 const Value& value) {
    const float mu = std::clamp(cos_theta, 1e-6f, 1.0f);
    const Vec3 w(std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu);
    const bool visible = distribution.type() == MicrofacetType::GGX;
    const MicrofacetDistribution sampler(distribution.type(), distribution.alpha_u(),
                                         distribution.alpha_v(), visible);
    const Quadrature q = gauss_legendre_unit(n);
    double sum = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const Vec3 m =
                sampler.sample(w, Vec2(float(q.nodes[size_t(i)]), float(q.nodes[size_t(j)])));
            const float w_m = dot(w, m);
            if (!(w_m > 0) || !(m.z > 0)) continue;
            const double visible_ratio =
                visible ? 1.0 : distribution.G1(w, m) * double(w_m) / (double(mu) * m.z);
            const double v = value(w, m);
            if (std::isfinite(visible_ratio) && std::isfinite(v))
                sum += q.weights[size_t(i)] * q.weights[size_t(j)] * visible_ratio * v;
        }
    return sum;
}

// The coating of (distribution, alpha, eta), built once per process: building one integrates
// its tables (about 0.1 s), and scenes often share a roughness between materials, and are
// loaded again (a worker per job, the parser's fuzz tests). A coating is 64 floats; the
// table is emptied when it reaches kMaxCoatings different ones.
std::shared_ptr<const RoughCoating> shared_coating(const MicrofacetDistribution& distribution,
                                                   float eta) {
    using Key = std::tuple<int, float, bool, float>;
    constexpr size_t kMaxCoatings = 1024;
    static std::mutex mutex;
    static std::map<Key, std::shared_ptr<const RoughCoating>> coatings;
    const Key key{int(distribution.type()), distribution.alpha_u(), distribution.sample_visible(),
                  eta};
    std::lock_guard<std::mutex> lock(mutex);
    if (auto it = coatings.find(key); it != coatings.end()) return it->second;
    if (coatings.size() >= kMaxCoatings) coatings.clear();
    auto coating = std::make_shared<const RoughCoating>(distribution, eta);
    coatings[key] = coating;
    return coating;
}

}  // namespace

float rough_interface_transmittance(const MicrofacetDistribution& distribution, float cos_theta,
                                    float eta, int n) {
    return float(integrate_visible_normals(
        distribution, cos_theta, n, [&](const Vec3& w, const Vec3& m) -> double {
            const DielectricFresnel fresnel = fresnel_dielectric(dot(w, m), eta);
            if (fresnel.reflectance >= 1) return 0.0;
            const Vec3 t = refract(w, m, fresnel.cos_theta_t, fresnel.eta_ti);
            if (!(t.z < 0)) return 0.0;
            return (1.0 - fresnel.reflectance) * distribution.G1(t, m);
        }));
}

float rough_interface_reflectance(const MicrofacetDistribution& distribution, float cos_theta,
                                  float eta, int n) {
    return float(integrate_visible_normals(
        distribution, cos_theta, n, [&](const Vec3& w, const Vec3& m) -> double {
            const Vec3 r = reflect(w, m);
            if (!(r.z > 0)) return 0.0;
            return fresnel_dielectric(dot(w, m), eta).reflectance * distribution.G1(r, m);
        }));
}

RoughCoating::RoughCoating(const MicrofacetDistribution& distribution, float eta)
    : distribution_(distribution), eta_(eta) {
    for (int i = 0; i < kTableSize; ++i) {
        const float mu = std::max(1e-6f, float(i) / (kTableSize - 1));
        transmittance_[size_t(i)] = rough_interface_transmittance(distribution, mu, eta);
    }
    // Ri = 2 * integral_0^1 R_inside(mu) mu dmu by a composite Gauss-Legendre rule; the
    // integrand has a kink at the critical angle, hence many panels of few nodes.
    constexpr int kPanels = 24;
    const Quadrature q = gauss_legendre_unit(4);
    double sum = 0;
    for (int p = 0; p < kPanels; ++p)
        for (size_t k = 0; k < q.nodes.size(); ++k) {
            const double mu = (p + q.nodes[k]) / kPanels;
            sum += q.weights[k] / kPanels * mu *
                   rough_interface_reflectance(distribution, float(mu), 1.0f / eta);
        }
    internal_reflectance_ = float(2 * sum);
}

float RoughCoating::transmittance(float cos_theta) const {
    const float x = std::clamp(cos_theta, 0.0f, 1.0f) * (kTableSize - 1);
    const int i = std::min(int(x), kTableSize - 2);
    const float t = x - float(i);
    return (1 - t) * transmittance_[size_t(i)] + t * transmittance_[size_t(i + 1)];
}

RoughPlasticBsdf::RoughPlasticBsdf(std::shared_ptr<const RoughCoating> coating,
                                   const Rgb& diffuse_reflectance, const Rgb& specular_reflectance,
                                   bool nonlinear)
    : coating_(std::move(coating)),
      diffuse_reflectance_(diffuse_reflectance),
      specular_reflectance_(specular_reflectance),
      nonlinear_(nonlinear) {
    const PlasticBase base =
        plastic_base(diffuse_reflectance_, specular_reflectance_, coating_->internal_reflectance(),
                     coating_->eta(), nonlinear_);
    diffuse_scaled_ = base.diffuse_scaled;
    specular_sampling_weight_ = base.specular_sampling_weight;
}

std::shared_ptr<const Bsdf> RoughPlasticBsdf::create(const Properties& props) {
    if (props.has("alpha_u") || props.has("alpha_v"))
        throw props.error(props.has("alpha_u") ? "alpha_u" : "alpha_v",
                          "roughplastic is isotropic (as in Mitsuba 3): give alpha");
    const MicrofacetParams params = read_microfacet_params(props);
    if (params.varies())
        throw props.error("alpha",
                          "roughplastic takes a float alpha, not a texture (as in Mitsuba 3)");
    const float eta = read_relative_ior(props, *lookup_dielectric_ior("polypropylene"));
    if (eta == 1.0f) throw props.error("int_ior", "equals ext_ior: the coating would be invisible");
    const RgbParam kd = read_reflectance_param(props, "diffuse_reflectance", Rgb(0.5f));
    const RgbParam ks = read_reflectance_param(props, "specular_reflectance", Rgb(1.0f));
    const bool nonlinear = props.get_bool("nonlinear", false);
    std::shared_ptr<const RoughCoating> coating = shared_coating(params.mean(), eta);
    return plain_or_textured(
        kd.varies() || ks.varies(), [coating, kd, ks, nonlinear](const Vec2* uv) {
            return make_bsdf_at<RoughPlasticBsdf>(uv, coating, kd.at(uv), ks.at(uv), nonlinear);
        });
}

float RoughPlasticBsdf::specular_probability(float cos_theta) const {
    const float t = coating_->transmittance(cos_theta);
    const float specular = (1.0f - t) * specular_sampling_weight_;
    const float diffuse = t * (1.0f - specular_sampling_weight_);
    return specular + diffuse > 0 ? specular / (specular + diffuse) : 1.0f;
}

Rgb RoughPlasticBsdf::f(const Vec3& wo, const Vec3& wi, TransportMode) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0f);
    const MicrofacetDistribution& distribution = coating_->distribution();
    Rgb result = diffuse_scaled_ * (coating_->transmittance(wo.z) * coating_->transmittance(wi.z));
    const Vec3 m = normalize(wo + wi);
    const float D = distribution.D(m);
    if (D > 0) {
        const float F = fresnel_dielectric(dot(wo, m), coating_->eta()).reflectance;
        const float G = distribution.G(wo, wi, m);
        result += specular_reflectance_ * (F * D * G / (4.0f * wo.z * wi.z));
    }
    return result.is_finite() ? result : Rgb(0.0f);
}

float RoughPlasticBsdf::sample_density(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0.0f;
    const float p_specular = specular_probability(wo.z);
    float result = (1.0f - p_specular) * wi.z * kInvPi;
    const Vec3 m = normalize(wo + wi);
    const float wo_dot_m = dot(wo, m);
    if (wo_dot_m > 0) {
        // Jacobian of the reflection map m -> wi: d omega_m / d omega_i = 1 / (4 wo.m).
        const float specular = coating_->distribution().pdf(wo, m) / (4.0f * wo_dot_m);
        if (std::isfinite(specular)) result += p_specular * specular;
    }
    return result;
}

BsdfPdf RoughPlasticBsdf::pdf_w(const Vec3& wo, const Vec3& wi) const {
    return {sample_density(wo, wi), sample_density(wi, wo)};
}

std::optional<BsdfSample> RoughPlasticBsdf::sample(const Vec3& wo, float u_lobe, Vec2 u,
                                                   TransportMode mode) const {
    if (wo.z <= 0 || !is_finite(wo)) return std::nullopt;
    BsdfSample s;
    if (u_lobe < specular_probability(wo.z)) {
        s.wi = reflect(wo, coating_->distribution().sample(wo, u));
        s.lobe = kLobeGlossyReflection;
    } else {
        s.wi = warp::square_to_cosine_hemisphere(u);
        s.lobe = kLobeDiffuseReflection;
    }
    if (!(s.wi.z > 0)) return std::nullopt;
    // Weight from the same f and pdf that evaluation reports, so MIS sees consistent values.
    s.pdf_w = pdf_w(wo, s.wi);
    if (!(s.pdf_w.forward > 0)) return std::nullopt;
    s.weight = f(wo, s.wi, mode) * (s.wi.z / s.pdf_w.forward);
    if (!s.weight.is_finite()) return std::nullopt;
    return s;
}

std::string RoughPlasticBsdf::to_string() const {
    const MicrofacetDistribution& distribution = coating_->distribution();
    std::ostringstream out;
    out << "roughplastic(" << render::to_string(distribution.type()) << ", alpha "
        << distribution.alpha_u() << ", diffuse_reflectance " << diffuse_reflectance_
        << ", specular_reflectance " << specular_reflectance_ << ", eta " << coating_->eta()
        << (nonlinear_ ? ", nonlinear" : "") << ")";
    return out.str();
}

}  // namespace render
