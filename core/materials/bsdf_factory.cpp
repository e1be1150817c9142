#include "core/materials/bsdf_factory.h"

#include "core/base/plugin_table.h"

#include "core/materials/blend.h"
#include "core/materials/bump_map.h"
#include "core/materials/conductor.h"
#include "core/materials/dielectric.h"
#include "core/materials/diffuse.h"
#include "core/materials/diffuse_transmission.h"
#include "core/materials/hair.h"
#include "core/materials/normal_map.h"
#include "core/materials/null_bsdf.h"
#include "core/materials/phong.h"
#include "core/materials/plastic.h"
#include "core/materials/rough_conductor.h"
#include "core/materials/rough_dielectric.h"
#include "core/materials/rough_plastic.h"
#include "core/materials/thin_dielectric.h"
#include "core/materials/twosided.h"

namespace render {
namespace {

constexpr Plugin<std::shared_ptr<const Bsdf> (*)(const Properties&)> kPlugins[] = {
    {"diffuse", &DiffuseBsdf::create},
    {"twosided", &TwoSidedBsdf::create},
    {"diffusetransmission", &DiffuseTransmissionBsdf::create},  // pbrt-v4's; ours in XML
    {"hair", &HairBsdf::create},                                // pbrt-v4's; ours in XML
    {"conductor", &ConductorBsdf::create},
    {"roughconductor", &RoughConductorBsdf::create},
    {"dielectric", &DielectricBsdf::create},
    {"roughdielectric", &RoughDielectricBsdf::create},
    {"thindielectric", &ThinDielectricBsdf::create},
    {"plastic", &PlasticBsdf::create},
    {"roughplastic", &RoughPlasticBsdf::create},
    {"phong", &PhongBsdf::create},
    {"null", &NullBsdf::create},
    {"blendbsdf", &BlendBsdf::create},
    {"mask", &BlendBsdf::create_mask},
    {"normalmap", &NormalMapBsdf::create},
    {"bumpmap", &BumpMapBsdf::create},
};

}  // namespace

std::shared_ptr<const Bsdf> make_bsdf(const Properties& props) {
    return find_plugin(kPlugins, props, "bsdf").create(props);
}

}  // namespace render
