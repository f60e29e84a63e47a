#pragma once
/// The field a body reads: B and its gradient at a world point and, where it is closed-form, the field's curvature
/// along a vector (the stiffness a magnet's potential adds to its position; the rod's Hessian needs it). The rod
/// solver, growth and the MPM solver all sample the magnets through it.

#include <concepts>
#include <cstddef>
#include <functional>
#include <type_traits>
#include <utility>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::magnetics {

/// Field and gradient at a world point [T, T/m]. Any callable Vec3 → FieldSample converts to it (no curvature then);
/// field_function adds the curvature when every source has it in closed form.
class FieldFunction {
 public:
  using Sample = std::function<FieldSample(const Vec3&)>;
  /// (x, w) ↦ Σ_i w_i ∂²B_i/∂x∂x [T/m² times w], symmetric.
  using Curvature = std::function<Mat3(const Vec3&, const Vec3&)>;

  FieldFunction() = default;
  FieldFunction(std::nullptr_t) {}  // NOLINT(google-explicit-constructor): "no field", as for std::function
  template <class F>
    requires(!std::same_as<std::remove_cvref_t<F>, FieldFunction> && std::is_invocable_r_v<FieldSample, F&, const Vec3&>)
  FieldFunction(F sample) : m_sample(std::move(sample)) {}  // NOLINT(google-explicit-constructor)
  FieldFunction(Sample sample, Curvature curvature) : m_sample(std::move(sample)), m_curvature(std::move(curvature)) {}

  FieldSample operator()(const Vec3& x) const { return m_sample(x); }
  explicit operator bool() const { return static_cast<bool>(m_sample); }
  /// Empty when the curvature is not known in closed form (callers difference the gradient instead).
  const Curvature& curvature() const { return m_curvature; }

 private:
  Sample m_sample;
  Curvature m_curvature;
};

/// The field of `model` with its sources at `poses` (copied), with the gradient only when some source has one (a
/// uniform-only model evaluates none: usage counter kGradientField) and the curvature when every source has it in
/// closed form (uniform fields and dipoles).
FieldFunction field_function(const FieldModel& model, std::vector<Pose> poses);

}  // namespace magvine::magnetics
