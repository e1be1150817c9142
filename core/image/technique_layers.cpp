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

TechniqueLayers::TechniqueLayers(LayerMode mode, int width, int height) : mode_(mode) {
    if (mode == LayerMode::Techniques) {
        names_ = {"connection", "merging"};
    } else if (mode == LayerMode::PathVertices) {
        for (int n = 2; n <= kMaxVertices; ++n)
            for (int s = 0; s < n; ++s)
                names_.push_back("s" + std::to_string(s) + "_t" + std::to_string(n - s));
    }
    buffers_.assign(names_.size(), AccumulationBuffer(width, height));
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

}  // namespace render
