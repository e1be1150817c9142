#include "core/image/image.h"

namespace render {

Image AccumulationBuffer::average(double count) const {
    Image image(width_, height_);
    double scale = count > 0 ? 1.0 / count : 0.0;
    float* out = image.data();
    for (size_t i = 0; i < rgb_.size(); ++i) out[i] = float(rgb_[i] * scale);
    return image;
}

}  // namespace render
