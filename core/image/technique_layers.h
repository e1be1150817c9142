#pragma once

// Per-technique images on request, written as extra EXR layers next to the main image:
//   Techniques:   "connection" (every connection technique: emission hits, next-event
//                 estimation, vertex connections, light tracing) and "merging" (vertex
//                 merging), as the VCM thesis shows them side by side;
//   PathVertices: one image per (s, t) technique of PT/BPT/VCM connections, s light vertices
//                 and t eye vertices (camera included), for paths of up to kMaxVertices
//                 vertices (longer paths only reach the main image);
//   Variance:     no technique: one buffer, the sum over iterations of each iteration's pixel
//                 values squared, from which the per-pixel error layers are written
//                 (core/image/variance_layers.h); render_iterations fills it, not the integrators.
// The layers of an iteration sum exactly like the image (they are part of IterationResult).

#include <cstdint>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace render {

enum class LayerMode { None, Techniques, PathVertices, Variance };
enum class Technique { Connection, Merging };

class TechniqueLayers {
  public:
    static constexpr int kMaxVertices = 6;

    TechniqueLayers() = default;
    TechniqueLayers(LayerMode mode, int width, int height);
    // The layers' names in the mode, in buffer order (also the order a worker reports them).
    static std::vector<std::string> names(LayerMode mode);

    LayerMode mode() const { return mode_; }
    bool enabled() const { return mode_ != LayerMode::None; }
    // Whether integrators write into the layers (Variance is filled by render_iterations).
    bool per_technique() const {
        return mode_ == LayerMode::Techniques || mode_ == LayerMode::PathVertices;
    }
    size_t size() const { return buffers_.size(); }
    const std::string& name(size_t i) const { return names_[i]; }
    const AccumulationBuffer& buffer(size_t i) const { return buffers_[i]; }
    AccumulationBuffer& buffer(size_t i) { return buffers_[i]; }

    // Layer receiving a contribution of technique `kind` with s light and t eye vertices, or
    // -1 when no layer records it.
    int index(Technique kind, int s, int t) const;
    void add(int index, size_t pixel, const Rgb& value) {
        if (index >= 0 && value.is_finite()) buffers_[size_t(index)].add(pixel, value);
    }
    void add(const TechniqueLayers& other);
    // Each layer's mean over `count` iterations; layers that never received a contribution
    // are left out (they would only fill the file with zeros).
    std::vector<NamedLayer> named_averages(uint64_t count) const;

  private:
    LayerMode mode_ = LayerMode::None;
    std::vector<std::string> names_;
    std::vector<AccumulationBuffer> buffers_;
};

// Where an integrator writes one pixel's technique contributions (nothing if layers is null).
struct LayerSink {
    TechniqueLayers* layers = nullptr;
    size_t pixel = 0;
    void add(Technique kind, int s, int t, const Rgb& value) const {
        if (layers) layers->add(layers->index(kind, s, t), pixel, value);
    }
};

}  // namespace render
