#pragma once
/// Superposition of field sources, each with its own pose.
///
/// FieldModel is immutable (what the magnets are); the poses are state (where they are now) and are passed
/// to every evaluation, so a controller can move magnets over time without touching the model.

#include <span>
#include <string>
#include <variant>
#include <vector>

#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_sample.hpp"
#include "magvine/magnetics/pose.hpp"

namespace magvine::magnetics {

/// Spatially uniform field (e.g. Helmholtz coils): B is constant in the source frame, G = 0.
struct UniformSource {
  Vec3 b = Vec3::Zero();  ///< flux density in the source frame [T]
};

/// Point dipole at the source origin.
struct DipoleSource {
  Vec3 moment = Vec3::Zero();  ///< dipole moment in the source frame [A·m²]
};

/// One source: exact cylinder, point dipole or uniform field.
using FieldSource = std::variant<UniformSource, DipoleSource, CylinderMagnet>;

/// The magnets of a scene.
struct FieldModel {
  std::vector<FieldSource> sources;
  /// Pose of each source as declared (t = 0); same length as `sources`.
  std::vector<Pose> rest_poses;
  /// Human-readable label of each source (e.g. "magnets[0] cylinder").
  std::vector<std::string> names;

  /// Appends a source with its rest pose.
  void add(FieldSource source, const Pose& pose, std::string name = {});
  std::size_t size() const { return sources.size(); }
  /// False when every source is uniform: then G ≡ 0 and callers need not ask for it.
  bool has_gradient() const;
  /// True when field_curvature is closed-form for every source (uniform fields and dipoles).
  bool has_analytic_curvature() const;
};

/// B at world point x [T], poses.size() == model.size().
Vec3 field(const FieldModel& model, std::span<const Pose> poses, const Vec3& x);
/// B and G at world point x, world frame.
FieldSample field_gradient(const FieldModel& model, std::span<const Pose> poses, const Vec3& x);

/// Σ_i w_i ∂²B_i/∂x∂x at world point x for a fixed world vector w [T/m²·w] (the field's curvature along w, e.g. the
/// stiffness a magnet's potential −m·B adds to its position), symmetric; closed-form for dipoles, zero for uniform
/// fields. Precondition: model.has_analytic_curvature().
Mat3 field_curvature(const FieldModel& model, std::span<const Pose> poses, const Vec3& x, const Vec3& w);

/// Batch forms: out[i] for points[i]; out.size() == points.size(). Loop over sources outside, points inside.
void field_batch(const FieldModel& model, std::span<const Pose> poses, std::span<const Vec3> points,
                 std::span<Vec3> out);
void field_gradient_batch(const FieldModel& model, std::span<const Pose> poses, std::span<const Vec3> points,
                          std::span<FieldSample> out);

}  // namespace magvine::magnetics
