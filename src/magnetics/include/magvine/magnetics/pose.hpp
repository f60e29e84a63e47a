#pragma once

#include "magvine/core/eigen_types.hpp"

namespace magvine::magnetics {

/// Placement of a field source: local → world is x = rotation · p + position.
struct Pose {
  /// Origin of the local frame (the magnet's centre), world frame [m].
  Vec3 position = Vec3::Zero();
  /// Orthonormal rotation, columns are the local axes in world coordinates.
  Mat3 rotation = Mat3::Identity();

  /// World point → local coordinates.
  Vec3 to_local(const Vec3& x) const { return rotation.transpose() * (x - position); }

  /// Pose whose local z axis is `axis` (any non-zero vector); the local x axis is chosen deterministically.
  static Pose from_axis(const Vec3& position, const Vec3& axis);
  /// Pose with local z = `axis` and local x = the part of `direction` perpendicular to `axis`.
  /// Both must be non-zero and not parallel (programmer error otherwise; files are validated by the loader).
  static Pose from_axis_direction(const Vec3& position, const Vec3& axis, const Vec3& direction);
};

}  // namespace magvine::magnetics
