#include "core/materials/bsdf_factory.h"

#include "core/materials/conductor.h"
#include "core/materials/dielectric.h"
#include "core/materials/diffuse.h"
#include "core/materials/null_bsdf.h"
#include "core/materials/phong.h"
#include "core/materials/plastic.h"
#include "core/materials/rough_conductor.h"
#include "core/materials/rough_dielectric.h"
#include "core/materials/twosided.h"

namespace render {
namespace {

struct BsdfPlugin {
    const char* name;
    std::shared_ptr<const Bsdf> (*create)(const Properties&);
};

constexpr BsdfPlugin kPlugins[] = {
    {"diffuse", &DiffuseBsdf::create},
    {"twosided", &TwoSidedBsdf::create},
    {"conductor", &ConductorBsdf::create},
    {"roughconductor", &RoughConductorBsdf::create},
    {"dielectric", &DielectricBsdf::create},
    {"roughdielectric", &RoughDielectricBsdf::create},
    {"plastic", &PlasticBsdf::create},
    {"phong", &PhongBsdf::create},
    {"null", &NullBsdf::create},
};

}  // namespace

std::shared_ptr<const Bsdf> make_bsdf(const Properties& props) {
    for (const BsdfPlugin& plugin : kPlugins)
        if (props.type() == plugin.name) return plugin.create(props);
    std::string supported;
    for (const BsdfPlugin& plugin : kPlugins)
        supported += std::string(supported.empty() ? "" : ", ") + plugin.name;
    throw SceneError(props.where(),
                     "unknown bsdf type \"" + props.type() + "\" (supported: " + supported + ")");
}

}  // namespace render
