#include "core/scene/volume_emitter.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/math/constants.h"
#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/sampling/rng.h"
#include "core/scene/scene.h"
#include "core/shapes/instance.h"

namespace render {
namespace {

// Cells per axis of a grid medium's sampling lattice, and the points that estimate each cell's
// weight: 16^3 cells, 8 points each (32768 look-ups at load).
constexpr int kGridResolution = 16;
constexpr int kPointsPerCell = 8;
// The probe ray's direction: not along an axis, so that it does not graze the edges of boxes.
// Surfaces without media a probe passes before it gives up (as medium_segment.h's limit).
constexpr int kMaxProbeCrossings = 256;
const Vec3 kProbeDirection = normalize(Vec3(0.5377f, 0.7071f, 0.4594f));

float source_luminance(const Medium& m, const Vec3& p) {
    const Rgb sigma_a = m.sigma_t(p) - m.sigma_s(p);
    const Rgb s =
        Rgb(std::max(sigma_a.r, 0.0f), std::max(sigma_a.g, 0.0f), std::max(sigma_a.b, 0.0f)) *
        m.radiance(p);
    const float l = s.luminance();
    return std::isfinite(l) && l > 0 ? l : 0.0f;
}

}  // namespace

const Medium* medium_seen_from(const Scene& scene, const Vec3& p, const Vec3& d, float distance,
                               const Medium* medium_there) {
    Ray ray(p, d, 0.0f, distance);
    for (int crossing = 0; crossing <= kMaxProbeCrossings; ++crossing) {
        SurfaceInteraction si;
        if (!scene.intersect(ray, si)) return medium_there;
        const Shape& shape = *si.shape;
        // Traced from the far end toward p, the path would cross this surface last, into the side
        // facing p: its interior when d goes along the geometric normal (medium_interface.h).
        // Surfaces that declare none (a diffuse ball in the flame) keep the medium around them.
        if (is_medium_transition(shape))
            return dot(d, si.geometric_normal) > 0 ? shape.interior : shape.exterior;
        ray = scene.spawn_ray(si.p, si.geometric_normal, d);
        ray.t_max = distance - dot(si.p - p, d);
        if (!(ray.t_max > 0)) return medium_there;
    }
    return nullptr;
}

bool point_in_medium(const Scene& scene, const Vec3& p, const Medium* medium) {
    return medium_seen_from(scene, p, kProbeDirection, kInfinity, nullptr) == medium;
}

Aabb volume_emitter_region(const Scene& scene, const Medium* medium, std::string& why) {
    for (const auto& instance : scene.instances())
        if (instance->group().has_media()) {
            why = "instanced shapes bound media (not supported for emitting media)";
            return Aabb{};
        }
    Aabb box;
    for (const auto& shape : scene.shapes())
        if (shape->interior == medium || shape->exterior == medium) box.expand(shape->bounds());
    if (box.empty()) {
        why = "no shape bounds it (an unbounded emitter)";
        return Aabb{};
    }
    for (int a = 0; a < 3; ++a)
        if (!(box.hi[a] > box.lo[a]) || !std::isfinite(box.hi[a] - box.lo[a])) {
            why = "its bounding shapes enclose no volume";
            return Aabb{};
        }
    // A medium is entered only across the shapes that declare it, all inside the box: it is
    // bounded unless the camera sits in it outside them. (An open surface that declares it, a
    // rectangle, lets it extend; the scene format cannot tell, as for volpt.)
    const auto outside_box = [&](const Vec3& p) {
        for (int a = 0; a < 3; ++a)
            if (p[a] < box.lo[a] || p[a] > box.hi[a]) return true;
        return false;
    };
    if (scene.camera_medium() == medium && outside_box(scene.camera().position())) {
        why = "the camera is in it outside its bounding shapes (an unbounded emitter)";
        return Aabb{};
    }
    return box;
}

VolumeEmitter::VolumeEmitter(const Scene& scene, const Medium& medium, const Aabb& box,
                             std::string name)
    : scene_(scene), emitting_medium_(medium), box_(box), name_(std::move(name)) {
    this->medium = &medium;
    resolution_ = medium.is_homogeneous() ? 1 : kGridResolution;
    cell_size_ = (box_.hi - box_.lo) * (1.0f / float(resolution_));
    cell_volume_ = cell_size_.x * cell_size_.y * cell_size_.z;
    const int n = resolution_ * resolution_ * resolution_;
    std::vector<float> w(size_t(n), 0.0f);
    Rng rng(StreamKey{0x766f6c756d65ULL, 0, 0, 0});  // fixed: the same lattice every load
    double sum = 0;
    for (int i = 0; i < n; ++i) {
        const Vec3 corner = box_.lo + Vec3(float(i % resolution_) * cell_size_.x,
                                           float((i / resolution_) % resolution_) * cell_size_.y,
                                           float(i / (resolution_ * resolution_)) * cell_size_.z);
        double cell = 0;
        for (int k = 0; k < kPointsPerCell; ++k) {
            const Vec3 u = rng.next_3d();
            cell += source_luminance(medium, corner + u * cell_size_);
        }
        w[size_t(i)] = float(cell / kPointsPerCell);
        sum += w[size_t(i)];
    }
    const float mean = float(sum / n);
    // Half uniform: positive wherever the integrand is (header comment).
    for (float& x : w) x = 0.5f * mean + 0.5f * x;
    cells_ = Distribution1D(w);
    // The emitted power 4 pi integral sigma_a L_e dV, as a colour with the estimate's luminance
    // (only its luminance selects lights).
    const double volume = double(cell_volume_) * n;
    const float luminance = float(4.0 * kPi * volume * sum / n);
    power_ = Rgb(luminance > 0 ? luminance : 1e-30f);
}

int VolumeEmitter::cell_index(const Vec3& p) const {
    int idx[3];
    for (int a = 0; a < 3; ++a) {
        const float f = (p[a] - box_.lo[a]) / cell_size_[a];
        idx[a] = std::clamp(int(std::floor(f)), 0, resolution_ - 1);
    }
    return idx[0] + resolution_ * (idx[1] + resolution_ * idx[2]);
}

VolumePointSample VolumeEmitter::sample_point(const Vec3& u) const {
    float probability = 0, remapped = 0;
    const size_t c = cells_.sample_discrete(u.x, &probability, &remapped);
    const int i = int(c);
    const Vec3 corner = box_.lo + Vec3(float(i % resolution_) * cell_size_.x,
                                       float((i / resolution_) % resolution_) * cell_size_.y,
                                       float(i / (resolution_ * resolution_)) * cell_size_.z);
    VolumePointSample s;
    s.p = corner + Vec3(std::min(remapped, 0x1.fffffep-1f), u.y, u.z) * cell_size_;
    s.pdf_volume = probability / cell_volume_;
    s.source = source_in_medium(s.p);
    return s;
}

float VolumeEmitter::pdf_volume(const Vec3& p) const {
    for (int a = 0; a < 3; ++a)
        if (!(p[a] >= box_.lo[a] && p[a] <= box_.hi[a])) return 0.0f;
    return cells_.discrete_probability(size_t(cell_index(p))) / cell_volume_;
}

Rgb VolumeEmitter::source(const Vec3& p) const {
    return contains(p) ? source_in_medium(p) : Rgb(0.0f);
}

Rgb VolumeEmitter::source_seen_from(const Vec3& p, const Vec3& d, float distance,
                                    const Medium* medium_there) const {
    return medium_seen_from(scene_, p, d, distance, medium_there) == &emitting_medium_
               ? source_in_medium(p)
               : Rgb(0.0f);
}

Rgb VolumeEmitter::source_leaving(const Vec3& p, const Vec3& d) const {
    SurfaceInteraction si;
    if (scene_.intersect(Ray(p, d), si) && is_medium_transition(*si.shape)) {
        const Medium* here =
            dot(d, si.geometric_normal) > 0 ? si.shape->interior : si.shape->exterior;
        return here == &emitting_medium_ ? source_in_medium(p) : Rgb(0.0f);
    }
    return source(p);
}

Rgb VolumeEmitter::source_in_medium(const Vec3& p) const {
    const Rgb sigma_a = emitting_medium_.sigma_t(p) - emitting_medium_.sigma_s(p);
    const Rgb s =
        Rgb(std::max(sigma_a.r, 0.0f), std::max(sigma_a.g, 0.0f), std::max(sigma_a.b, 0.0f)) *
        emitting_medium_.radiance(p);
    return s.is_finite() ? s : Rgb(0.0f);
}

bool VolumeEmitter::contains(const Vec3& p) const {
    return point_in_medium(scene_, p, &emitting_medium_);
}

std::string VolumeEmitter::to_string() const {
    std::ostringstream os;
    os << "volume_emitter(" << name_ << ", " << resolution_ << "^3 cells)";
    return os.str();
}

}  // namespace render
