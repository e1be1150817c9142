#pragma once

// The common part of the BSDFs that only tilt the shading frame of one nested BSDF (normal and
// bump maps): Scene::intersect calls their shading_frame() at every hit and then resolves the
// nested material there (at()), so their own f/pdf/sample are the nested BSDF's and are used
// only without a hit. They must be the outermost BSDF (twosided/blend would drop the tilt).

#include <memory>
#include <string>

#include "core/base/error.h"
#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class ShadingFrameBsdf : public Bsdf {
  public:
    bool changes_shading_frame() const override { return true; }
    std::shared_ptr<const Bsdf> at(Vec2 uv) const override {
        return nested_->varies() ? nested_->at(uv) : nested_;
    }

    // Without a hit (nothing in the renderer evaluates it so): the nested BSDF.
    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override {
        return nested_->f(wo, wi, mode);
    }
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override { return nested_->pdf_w(wo, wi); }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override {
        return nested_->sample(wo, u_lobe, u, mode);
    }
    uint32_t lobes() const override { return nested_->lobes(); }

  protected:
    explicit ShadingFrameBsdf(std::shared_ptr<const Bsdf> nested) : nested_(std::move(nested)) {
        varies_ = true;  // resolved at every hit: the frame changes even for a plain nested BSDF
    }

    // The one nested BSDF of a `plugin` ("normalmap", "bumpmap") in the scene file, refused at
    // its line if there is not exactly one or if it tilts the frame itself.
    static const std::shared_ptr<const Bsdf>& the_nested_bsdf(const Properties& props,
                                                              const std::string& plugin) {
        if (props.nested_bsdfs.size() != 1)
            throw SceneError(props.where(), "bsdf \"" + plugin + "\" needs one nested bsdf, got " +
                                                std::to_string(props.nested_bsdfs.size()));
        const std::shared_ptr<const Bsdf>& nested = props.nested_bsdfs[0];
        if (nested->changes_shading_frame())
            throw SceneError(props.where(),
                             "bsdf \"" + plugin + "\" cannot wrap another bumpmap or a normalmap");
        return nested;
    }

    std::shared_ptr<const Bsdf> nested_;
};

}  // namespace render
