#include "core/image/exr_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <optional>

#include "core/base/memory_budget.h"
#include "core/image/image_plugin.h"

namespace render {
namespace {

// The metadata key under which the plugin's pixel sink leaves its own error for the caller.
constexpr const char* kSinkError = "render:sink-error";

// The decoded pixels (float), charged to the scene's memory budget before they are allocated.
uint64_t pixel_bytes(int width, int height, size_t channels) {
    return saturating_product(
        saturating_product(uint64_t(std::max(width, 0)), uint64_t(std::max(height, 0))),
        4 * channels);
}
std::string pixels_name(int width, int height) {
    return std::to_string(width) + " x " + std::to_string(height) + " image";
}

// "YYYY:MM:DD HH:MM:SS" local time: the capDate OpenImageIO puts in every EXR it writes.
std::string capture_date() {
    std::time_t now = std::time(nullptr);
    std::tm local{};
    localtime_r(&now, &local);
    char text[32];
    std::strftime(text, sizeof text, "%Y:%m:%d %H:%M:%S", &local);
    return text;
}

bool has_exr_magic(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    unsigned char magic[4] = {0, 0, 0, 0};
    in.read(reinterpret_cast<char*>(magic), 4);
    return in && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

// The named float channels of the first part's data window, interleaved in `names`' order
// (charged to the scene memory budget).
void read_float_channels(Imf::InputFile& in, const std::filesystem::path& file,
                         const std::vector<std::string>& names, int& width, int& height,
                         std::vector<float>& pixels) {
    const Imath::Box2i window = in.header().dataWindow();
    width = window.max.x - window.min.x + 1;
    height = window.max.y - window.min.y + 1;
    if (width <= 0 || height <= 0) throw ImageFileError(file, "the image has no pixels");
    charge_scene_memory(pixel_bytes(width, height, names.size()),
                        file.string() + ": " + pixels_name(width, height));
    pixels.assign(size_t(width) * size_t(height) * names.size(), 0.0f);
    Imf::FrameBuffer frame;
    const size_t x_stride = sizeof(float) * names.size();
    for (size_t c = 0; c < names.size(); ++c)
        frame.insert(names[c], Imf::Slice::Make(Imf::FLOAT, pixels.data() + c, window, x_stride,
                                                x_stride * size_t(width)));
    in.setFrameBuffer(frame);
    in.readPixels(window.min.y, window.max.y);
}

// The EXR through OpenEXR, or nullopt when it has channels this does not cover (the plugin
// reads those as OpenImageIO always did).
std::optional<ImageFileData> read_exr_file(const std::filesystem::path& file) {
    Imf::InputFile in(file.c_str());
    const Imf::Header& header = in.header();
    const Imf::ChannelList& list = header.channels();
    size_t channel_count = 0;
    for (auto it = list.begin(); it != list.end(); ++it) ++channel_count;
    std::vector<std::string> names;
    if (list.findChannel("R") && list.findChannel("G") && list.findChannel("B"))
        names = {"R", "G", "B"};
    else if (list.findChannel("Y") && !list.findChannel("RY") && !list.findChannel("BY"))
        names = {"Y"};
    else if (channel_count == 1)
        names = {list.begin().name()};
    else
        return std::nullopt;
    for (const std::string& name : names) {
        const Imf::Channel& channel = *list.findChannel(name);
        if (channel.type == Imf::UINT || channel.xSampling != 1 || channel.ySampling != 1)
            return std::nullopt;
    }
    ImageFileData data;
    data.channels = int(names.size());
    read_float_channels(in, file, names, data.width, data.height, data.pixels);
    for (auto it = header.begin(); it != header.end(); ++it)
        if (auto text = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
            data.metadata[it.name()] = text->value();
    return data;
}

ImageFileData read_with_plugin(const std::filesystem::path& file) {
    const RenderImagePlugin* plugin;
    try {
        plugin = &image_plugin("to read " + file.string());
    } catch (const std::exception& e) {
        throw ImageFileError(file, e.what());
    }
    ImageFileData data;
    RenderImageReadSink sink;
    sink.context = &data;
    sink.begin = [](void* context, int width, int height, int channels, int integer_format,
                    const char* color_space) -> float* {
        try {
            auto& d = *static_cast<ImageFileData*>(context);
            d.width = width;
            d.height = height;
            d.channels = channels;
            d.integer_format = integer_format != 0;
            d.color_space = color_space ? color_space : "";
            charge_scene_memory(pixel_bytes(width, height, size_t(std::max(channels, 0))),
                                pixels_name(width, height));
            d.pixels.assign(size_t(width) * size_t(height) * size_t(channels), 0.0f);
            return d.pixels.data();
        } catch (const std::exception& e) {
            static_cast<ImageFileData*>(context)->metadata[kSinkError] = e.what();
            return nullptr;
        } catch (...) {
            return nullptr;
        }
    };
    sink.attribute = [](void* context, const char* name, const char* value) {
        try {
            static_cast<ImageFileData*>(context)->metadata[name] = value;
        } catch (...) {
        }
    };
    char error[2048] = "";
    if (plugin->read(file.c_str(), &sink, error, sizeof error) != 0) {
        if (auto it = data.metadata.find(kSinkError); it != data.metadata.end())
            throw SceneError(file.string() + ": " + it->second);  // the memory budget's refusal
        throw ImageFileError(file, error);
    }
    if (data.width <= 0 || data.height <= 0 || data.channels <= 0)
        throw ImageFileError(file, "the image has no pixels");
    return data;
}

}  // namespace

void write_exr(const std::filesystem::path& file, const Image& image,
               const std::map<std::string, std::string>& metadata,
               const std::vector<NamedLayer>& layers) {
    for (const NamedLayer& layer : layers)
        if (layer.image.width() != image.width() || layer.image.height() != image.height())
            throw std::invalid_argument("layer " + layer.name + " differs in size from the image");
    try {
        Imf::Header header(image.width(), image.height());
        header.compression() = Imf::ZIP_COMPRESSION;
        Imf::FrameBuffer frame;
        const size_t x_stride = 3 * sizeof(float), y_stride = x_stride * size_t(image.width());
        auto add = [&](const std::string& prefix, const Image& source) {
            const char* components[3] = {"R", "G", "B"};
            for (int c = 0; c < 3; ++c) {
                const std::string name = prefix + components[c];
                header.channels().insert(name, Imf::Channel(Imf::FLOAT));
                // OpenEXR only reads through the slices of an output file.
                char* base = reinterpret_cast<char*>(const_cast<float*>(source.data() + c));
                frame.insert(name, Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
            }
        };
        add("", image);
        for (const NamedLayer& layer : layers) add(layer.name + ".", layer.image);
        Imf::addCapDate(header, capture_date());
        for (const auto& [key, value] : metadata) header.insert(key, Imf::StringAttribute(value));
        Imf::OutputFile out(file.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(image.height());
    } catch (const std::exception& e) {
        throw std::runtime_error("cannot write " + file.string() + ": " + e.what());
    }
}

std::optional<Image> read_exr_layer(const std::filesystem::path& file, const std::string& layer) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) throw ImageFileError(file, "no such file");
    if (!has_exr_magic(file)) throw ImageFileError(file, "not an OpenEXR file");
    try {
        Imf::InputFile in(file.c_str());
        const std::vector<std::string> names = {layer + ".R", layer + ".G", layer + ".B"};
        for (const std::string& name : names) {
            const Imf::Channel* channel = in.header().channels().findChannel(name);
            if (!channel) return std::nullopt;
            if (channel->type == Imf::UINT || channel->xSampling != 1 || channel->ySampling != 1)
                throw ImageFileError(file, "layer " + layer + " is not a float RGB layer");
        }
        int width = 0, height = 0;
        std::vector<float> pixels;
        read_float_channels(in, file, names, width, height, pixels);
        Image image(width, height);
        std::copy(pixels.begin(), pixels.end(), image.data());
        return image;
    } catch (const ImageFileError&) {
        throw;
    } catch (const std::exception& e) {
        throw ImageFileError(file, e.what());
    }
}

ImageFileData read_image_file(const std::filesystem::path& file) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) throw ImageFileError(file, "no such file");
    if (has_exr_magic(file)) {
        std::optional<ImageFileData> data;
        try {
            data = read_exr_file(file);
        } catch (const ImageFileError&) {
            throw;
        } catch (const MemoryLimitExceeded&) {
            throw;  // names the file and the limit already
        } catch (const std::exception& e) {
            throw ImageFileError(file, e.what());
        }
        if (data) return std::move(*data);
    } else {
        std::string extension = file.extension().string();
        std::transform(extension.begin(), extension.end(), extension.begin(),
                       [](unsigned char c) { return char(std::tolower(c)); });
        if (extension == ".exr") throw ImageFileError(file, "not an OpenEXR file");
    }
    return read_with_plugin(file);
}

Image read_image(const std::filesystem::path& file, std::map<std::string, std::string>* metadata) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec))
        throw std::runtime_error("image file not found: " + file.string());
    ImageFileData data = read_image_file(file);
    if (metadata)
        for (auto& [key, value] : data.metadata) (*metadata)[key] = std::move(value);
    Image image(data.width, data.height);
    const size_t channels = size_t(data.channels);
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        const float* p = &data.pixels[i * channels];
        image.set(i, channels >= 3 ? Rgb(p[0], p[1], p[2]) : Rgb(p[0]));
    }
    return image;
}

void write_png_preview(const std::filesystem::path& file, const Image& image,
                       float exposure_scale) {
    std::vector<unsigned char> bytes(image.pixel_count() * 3);
    const float* src = image.data();
    for (size_t i = 0; i < bytes.size(); ++i) {
        float v = std::clamp(src[i] * exposure_scale, 0.0f, 1.0f);
        if (!std::isfinite(v)) v = 0;
        v = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
        bytes[i] = (unsigned char)std::lround(v * 255.0f);
    }
    const RenderImagePlugin* plugin;
    try {
        plugin = &image_plugin("to write " + file.string());
    } catch (const std::exception& e) {
        throw std::runtime_error("cannot write " + file.string() + ": " + e.what());
    }
    char error[2048] = "";
    if (plugin->write_rgb8(file.c_str(), image.width(), image.height(), bytes.data(), error,
                           sizeof error) != 0)
        throw std::runtime_error("cannot write " + file.string() + ": " + error);
}

}  // namespace render
