#include "core/textures/texture_factory.h"

#include "core/base/plugin_table.h"
#include "core/textures/bitmap_texture.h"
#include "core/textures/checkerboard_texture.h"
#include "core/textures/constant_texture.h"

namespace render {
namespace {

constexpr Plugin<std::shared_ptr<const Texture> (*)(const Properties&)> kPlugins[] = {
    {"bitmap", &BitmapTexture::create},
    {"checkerboard", &CheckerboardTexture::create},
};

}  // namespace

std::shared_ptr<const Texture> make_texture(const Properties& props) {
    return find_plugin(kPlugins, props, "texture").create(props);
}

std::shared_ptr<const Texture> read_texture(const Properties& props, const std::string& name,
                                            const Rgb& def) {
    if (std::shared_ptr<const Texture> texture = props.get_texture(name)) return texture;
    const Rgb value = props.get_rgb(name, def);
    if (!value.is_finite()) throw props.error(name, "must be finite");
    return std::make_shared<ConstantTexture>(value);
}

}  // namespace render
