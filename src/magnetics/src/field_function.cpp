#include "magvine/magnetics/field_function.hpp"

#include <memory>

#include "magvine/core/usage.hpp"

namespace magvine::magnetics {

FieldFunction field_function(const FieldModel& model, std::vector<Pose> poses) {
  if (model.has_gradient()) {
    usage::note(usage::Component::kGradientField);
    // One copy of the magnets, shared by the sample and the curvature.
    struct Posed {
      FieldModel model;
      std::vector<Pose> poses;
    };
    auto posed = std::make_shared<const Posed>(Posed{model, std::move(poses)});
    FieldFunction::Sample sample = [posed](const Vec3& x) { return field_gradient(posed->model, posed->poses, x); };
    if (!model.has_analytic_curvature()) return sample;
    return {std::move(sample),
            [posed](const Vec3& x, const Vec3& w) { return field_curvature(posed->model, posed->poses, x, w); }};
  }
  return [model, poses = std::move(poses)](const Vec3& x) {
    FieldSample sample;
    sample.b = field(model, poses, x);
    return sample;
  };
}

}  // namespace magvine::magnetics
