#include "core/textures/bitmap_texture.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <system_error>

#include "core/image/exr_io.h"
#include "core/image/srgb.h"

namespace render {
namespace {

// Brings u into one period of the wrap mode first, so that huge coordinates cannot overflow
// the texel index; the period (1 for repeat, 2 for mirror) maps texels onto themselves.
float reduce(float u, BitmapTexture::Wrap wrap) {
    switch (wrap) {
        case BitmapTexture::Wrap::Repeat:
            return u - std::floor(u);
        case BitmapTexture::Wrap::Mirror:
            return u - 2.0f * std::floor(0.5f * u);
        case BitmapTexture::Wrap::Clamp:
            break;
    }
    return std::clamp(u, -1.0f, 2.0f);
}

int wrap_index(int i, int n, BitmapTexture::Wrap wrap) {
    switch (wrap) {
        case BitmapTexture::Wrap::Repeat:
            i %= n;
            return i < 0 ? i + n : i;
        case BitmapTexture::Wrap::Mirror: {
            // Period 2n: 0 .. n-1, then n-1 .. 0.
            int m = i % (2 * n);
            if (m < 0) m += 2 * n;
            return m < n ? m : 2 * n - 1 - m;
        }
        case BitmapTexture::Wrap::Clamp:
            break;
    }
    return std::clamp(i, 0, n - 1);
}

BitmapTexture::Filter parse_filter(const Properties& props) {
    const std::string name = props.get_string("filter_type", "bilinear");
    if (name == "bilinear") return BitmapTexture::Filter::Bilinear;
    if (name == "nearest") return BitmapTexture::Filter::Nearest;
    throw props.error("filter_type", "unknown filter \"" + name + "\" (bilinear or nearest)");
}

BitmapTexture::Wrap parse_wrap(const Properties& props) {
    const std::string name = props.get_string("wrap_mode", "repeat");
    if (name == "repeat") return BitmapTexture::Wrap::Repeat;
    if (name == "mirror") return BitmapTexture::Wrap::Mirror;
    if (name == "clamp") return BitmapTexture::Wrap::Clamp;
    throw props.error("wrap_mode", "unknown wrap mode \"" + name + "\" (repeat, mirror or clamp)");
}

}  // namespace

BitmapTexture::BitmapTexture(std::vector<Rgb> texels, int width, int height, Filter filter,
                             Wrap wrap, const UvTransform& to_uv, std::string name)
    : texels_(std::move(texels)),
      width_(width),
      height_(height),
      filter_(filter),
      wrap_(wrap),
      to_uv_(to_uv),
      name_(std::move(name)) {
    if (width_ <= 0 || height_ <= 0 || texels_.size() != size_t(width_) * size_t(height_))
        throw std::invalid_argument("bitmap texture: " + std::to_string(texels_.size()) +
                                    " texels for " + std::to_string(width_) + " x " +
                                    std::to_string(height_));
    double sum[3] = {0, 0, 0};
    min_ = texels_[0].r, max_ = texels_[0].r;
    for (const Rgb& t : texels_)
        for (int c = 0; c < 3; ++c) {
            sum[c] += double(t[c]);
            min_ = std::min(min_, t[c]);
            max_ = std::max(max_, t[c]);
        }
    const double n = double(texels_.size());
    mean_ = Rgb(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n));
}

std::shared_ptr<const Texture> BitmapTexture::create(const Properties& props) {
    const std::string filename = props.get_string("filename");
    if (filename.empty()) throw props.error("filename", "empty file name");
    const bool raw = props.get_bool("raw", false);
    const Filter filter = parse_filter(props);
    const Wrap wrap = parse_wrap(props);
    const UvTransform to_uv(props.get_transform("to_uv", Transform()));
    if (!to_uv.is_finite()) throw props.error("to_uv", "the transform is not finite");
    const std::string format = props.get_string("format", "auto");
    if (format != "auto" && format != "variant" && format != "fp16")
        throw props.error("format", "unknown format \"" + format + "\" (auto, variant or fp16)");
    props.get_bool("accel", true);

    std::error_code ec;
    if (!std::filesystem::is_regular_file(filename, ec))
        throw props.error("filename", "image file not found: " + filename);
    ImageFileData file;
    try {
        file = read_image_file(filename);
    } catch (const ImageFileError& e) {
        throw props.error("filename", "cannot read " + filename + ": " + e.reason());
    }
    const size_t channels = size_t(file.channels);
    if (channels < 1 || channels > 4)
        throw props.error("filename", filename + " has " + std::to_string(channels) +
                                          " channels (a texture needs Y, YA, RGB or RGBA)");
    const bool decode = !raw && is_srgb_encoded(file.integer_format, file.color_space);
    std::vector<Rgb> texels(size_t(file.width) * size_t(file.height));
    for (size_t i = 0; i < texels.size(); ++i) {
        const float* p = &file.pixels[i * channels];
        Rgb c = channels >= 3 ? Rgb(p[0], p[1], p[2]) : Rgb(p[0]);
        if (!c.is_finite()) {
            throw props.error(
                "filename", filename + ": texel (" + std::to_string(i % size_t(file.width)) + ", " +
                                std::to_string(i / size_t(file.width)) + ") is not finite");
        }
        if (decode) c = Rgb(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
        texels[i] = c;
    }
    return std::make_shared<BitmapTexture>(std::move(texels), file.width, file.height, filter, wrap,
                                           to_uv,
                                           std::filesystem::path(filename).filename().string());
}

Rgb BitmapTexture::eval(Vec2 uv_in) const {
    const Vec2 uv = to_uv_.apply(uv_in);
    if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) return Rgb(0.0f);
    const float u = reduce(uv.x, wrap_) * float(width_);
    const float v = reduce(uv.y, wrap_) * float(height_);
    if (filter_ == Filter::Nearest) {
        const int x = wrap_index(int(std::floor(u)), width_, wrap_);
        const int y = wrap_index(int(std::floor(v)), height_, wrap_);
        return texel(x, y);
    }
    // Texel centres sit at half-integer positions.
    const float x = u - 0.5f, y = v - 0.5f;
    const float x0f = std::floor(x), y0f = std::floor(y);
    const float fx = x - x0f, fy = y - y0f;
    const int x0 = int(x0f), y0 = int(y0f);
    const int xa = wrap_index(x0, width_, wrap_), xb = wrap_index(x0 + 1, width_, wrap_);
    const int ya = wrap_index(y0, height_, wrap_), yb = wrap_index(y0 + 1, height_, wrap_);
    const Rgb top = texel(xa, ya) * (1.0f - fx) + texel(xb, ya) * fx;
    const Rgb bottom = texel(xa, yb) * (1.0f - fx) + texel(xb, yb) * fx;
    return top * (1.0f - fy) + bottom * fy;
}

std::string BitmapTexture::to_string() const {
    std::ostringstream out;
    out << "bitmap(" << name_ << ", " << width_ << " x " << height_ << ")";
    return out.str();
}

}  // namespace render
