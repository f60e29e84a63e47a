#include "magvine/magnetics/pose.hpp"

#include <cmath>

#include "magvine/core/check.hpp"

namespace magvine::magnetics {

Pose Pose::from_axis(const Vec3& position, const Vec3& axis) {
  MAGVINE_ASSERT(axis.norm() > 0.0);
  const Vec3 z = axis.normalized();
  // Seed with the world axis least aligned with z so the cross product is well conditioned.
  Eigen::Index i = 0;
  z.cwiseAbs().minCoeff(&i);
  const Vec3 seed = Vec3::Unit(i);
  return from_axis_direction(position, z, seed);
}

Pose Pose::from_axis_direction(const Vec3& position, const Vec3& axis, const Vec3& direction) {
  const Vec3 z = axis.normalized();
  const Vec3 x_raw = direction - z * z.dot(direction);
  MAGVINE_ASSERT(x_raw.norm() > 1e-12 * direction.norm());
  const Vec3 x = x_raw.normalized();
  Pose pose;
  pose.position = position;
  pose.rotation.col(0) = x;
  pose.rotation.col(1) = z.cross(x);
  pose.rotation.col(2) = z;
  return pose;
}

}  // namespace magvine::magnetics
