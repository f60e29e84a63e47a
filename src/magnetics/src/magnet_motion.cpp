#include "magvine/magnetics/magnet_motion.hpp"

#include <cmath>

#include <Eigen/Geometry>

#include "magvine/core/keyframes.hpp"
#include "magvine/core/units.hpp"

namespace magvine::magnetics {

MagnetKeyframe interpolate(const std::vector<MagnetKeyframe>& keys, double time) {
  const KeyframeSpan at = keyframe_span(keys.size(), time, [&](std::size_t k) { return keys[k].time; });
  if (at.before == at.after) return keys[at.before];
  const MagnetKeyframe& a = keys[at.before];
  const MagnetKeyframe& b = keys[at.after];
  MagnetKeyframe out;
  out.time = time;
  out.position = lerp(a.position, b.position, at.u);
  const Eigen::Quaterniond full = Eigen::Quaterniond::FromTwoVectors(a.axis, b.axis);
  out.axis = (Eigen::Quaterniond::Identity().slerp(at.u, full) * a.axis).normalized();
  return out;
}

Pose pose_at(const Pose& rest, const Vec3& position, const Vec3& axis) {
  Pose p = rest;
  p.position = position;
  p.rotation = Eigen::Quaterniond::FromTwoVectors(rest.rotation.col(2), axis).toRotationMatrix() * rest.rotation;
  return p;
}

std::vector<Pose> poses_at(const FieldModel& model, const std::vector<std::vector<MagnetKeyframe>>& keyframes,
                           double time) {
  std::vector<Pose> out = model.rest_poses;
  for (std::size_t i = 0; i < out.size() && i < keyframes.size(); ++i) {
    if (keyframes[i].empty()) continue;
    const MagnetKeyframe k = interpolate(keyframes[i], time);
    out[i] = pose_at(model.rest_poses[i], k.position, k.axis);
  }
  return out;
}

Vec3 UniformFieldSchedule::at(double t) const {
  if (rotating && t >= rotation_start) {
    const double angle = 2.0 * kPi * frequency * (t - rotation_start);
    return amplitude * (std::cos(angle) * start + std::sin(angle) * axis.cross(start));
  }
  if (keyframes.empty()) return Vec3::Zero();
  const KeyframeSpan span = keyframe_span(keyframes.size(), t, [&](std::size_t k) { return keyframes[k].first; });
  return lerp(keyframes[span.before].second, keyframes[span.after].second, span.u);
}

}  // namespace magvine::magnetics
