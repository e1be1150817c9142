#include "core/image/technique_layers.h"

namespace render {
namespace {

// Layers of PathVertices mode in order of vertex count n = s + t, then s.
int path_vertices_index(int s, int t) {
    const int n = s + t;
    // Vertex counts 2 .. n-1 contribute 2, 3, ..., n-1 layers each (s = 0 .. count-1).
    const int before = (n - 2) * (n + 1) / 2;
    return before + s;
}

}  // namespace

std::vector<std::string> TechniqueLayers::names(LayerMode mode) {
    std::vector<std::string> names;
    if (mode == LayerMode::Techniques) {
        names = {"connection", "merging"};
    } else if (mode == LayerMode::PathVertices) {
        for (int n = 2; n <= kMaxVertices; ++n)
            for (int s = 0; s < n; ++s)
                names.push_back(std::string("s")
                                    .append(std::to_string(s))
                                    .append("_t")
                                    .append(std::to_string(n - s)));
    } else if (mode == LayerMode::Variance) {
        names = {"sum_squares"};
    }
    return names;
}

TechniqueLayers::TechniqueLayers(LayerMode mode, int width, int height)
    : mode_(mode), names_(names(mode)) {
    // One buffer per layer, each made in place: no frame-sized prototype, which without
    // layers would be allocated and zeroed only to be thrown away.
    buffers_.reserve(names_.size());
    for (size_t i = 0; i < names_.size(); ++i) buffers_.emplace_back(width, height);
}

int TechniqueLayers::index(Technique kind, int s, int t) const {
    switch (mode_) {
        case LayerMode::Techniques:
            return kind == Technique::Connection ? 0 : 1;
        case LayerMode::PathVertices:
            if (kind != Technique::Connection || s < 0 || t < 1 || s + t > kMaxVertices) return -1;
            return path_vertices_index(s, t);
        default:
            return -1;
    }
}

void TechniqueLayers::add(const TechniqueLayers& other) {
    for (size_t i = 0; i < buffers_.size() && i < other.buffers_.size(); ++i)
        buffers_[i].add(other.buffers_[i]);
}

std::vector<NamedLayer> TechniqueLayers::named_averages(uint64_t count) const {
    std::vector<NamedLayer> out;
    for (size_t i = 0; i < buffers_.size(); ++i) {
        bool any = false;
        for (double v : buffers_[i].values()) any |= v != 0;
        if (any) out.push_back({names_[i], buffers_[i].average(double(count))});
    }
    return out;
}

}  // namespace render
