#pragma once

// Images: a float RGB image (what is written and read) and a double accumulation buffer (what
// iterations add into, so that summing many iterations or many workers loses nothing).

#include <cstddef>
#include <string>
#include <vector>

#include "core/math/vec.h"

namespace render {

class Image {
  public:
    Image() = default;
    Image(int width, int height)
        : width_(width), height_(height), rgb_(size_t(width) * height * 3) {}

    int width() const { return width_; }
    int height() const { return height_; }
    size_t pixel_count() const { return size_t(width_) * height_; }
    Rgb at(int x, int y) const { return at(size_t(y) * width_ + x); }
    Rgb at(size_t i) const { return {rgb_[3 * i], rgb_[3 * i + 1], rgb_[3 * i + 2]}; }
    void set(size_t i, const Rgb& c) {
        rgb_[3 * i] = c.r;
        rgb_[3 * i + 1] = c.g;
        rgb_[3 * i + 2] = c.b;
    }
    const float* data() const { return rgb_.data(); }
    float* data() { return rgb_.data(); }

  private:
    int width_ = 0, height_ = 0;
    std::vector<float> rgb_;  // interleaved RGB, rows top to bottom
};

class AccumulationBuffer {
  public:
    AccumulationBuffer() = default;
    AccumulationBuffer(int width, int height)
        : width_(width), height_(height), rgb_(size_t(width) * height * 3, 0.0) {}

    int width() const { return width_; }
    int height() const { return height_; }
    size_t pixel_count() const { return size_t(width_) * height_; }

    void add(size_t pixel, const Rgb& c) {
        rgb_[3 * pixel] += c.r;
        rgb_[3 * pixel + 1] += c.g;
        rgb_[3 * pixel + 2] += c.b;
    }
    void add(const AccumulationBuffer& other) {
        for (size_t i = 0; i < rgb_.size(); ++i) rgb_[i] += other.rgb_[i];
    }
    double channel(size_t pixel, int c) const { return rgb_[3 * pixel + c]; }
    const std::vector<double>& values() const { return rgb_; }
    std::vector<double>& values() { return rgb_; }

    // The buffer divided by `count` (e.g. the iteration count).
    Image average(double count) const;

  private:
    int width_ = 0, height_ = 0;
    std::vector<double> rgb_;
};

// An extra image stored as channels NAME.R, NAME.G, NAME.B after the main R, G, B (write_exr).
struct NamedLayer {
    std::string name;
    Image image;
};

}  // namespace render
