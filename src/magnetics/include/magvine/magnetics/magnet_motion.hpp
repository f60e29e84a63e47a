#pragma once
/// The magnets' poses over time and applied fields over time: keyframed magnet poses (positions linear, axes along
/// the great circle, held beyond the ends) and a uniform field that follows keyframes or rotates. Experiments (the
/// rod and vine) and MPM scenes read their fields through these.

#include <utility>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/pose.hpp"

namespace magvine::magnetics {

/// One magnet's pose at a time.
struct MagnetKeyframe {
  double time = 0.0;             ///< [s]
  Vec3 position = Vec3::Zero();  ///< the magnet's centre [m]
  Vec3 axis = Vec3::UnitZ();     ///< unit: the magnetisation axis (the source's local z)
};

/// The pose at `time` between the keyframes around it (times increasing): position linear, axis turned along the
/// great circle (slerp); held beyond the first and the last. `keys` non-empty.
MagnetKeyframe interpolate(const std::vector<MagnetKeyframe>& keys, double time);

/// The rest pose turned so that its z axis is `axis` (the smallest rotation) and moved to `position`.
Pose pose_at(const Pose& rest, const Vec3& position, const Vec3& axis);

/// The poses of `model`'s sources at `time`: source i at its keyframes `keyframes[i]` (interpolated) or, where that
/// list is empty (or `keyframes` is shorter), at its rest pose.
std::vector<Pose> poses_at(const FieldModel& model, const std::vector<std::vector<MagnetKeyframe>>& keyframes,
                           double time);

/// A spatially uniform applied field over time [T] (Helmholtz coils, an MPM scene's `field:`): keyframes (t, B)
/// linear between and held beyond the ends, and/or a field of constant `amplitude` rotating at `frequency` about
/// `axis` from `start` once t reaches `rotation_start` (B(t) = amplitude (cos ωτ · start + sin ωτ · axis × start),
/// ω = 2π·frequency, τ = t − rotation_start); before it the keyframes apply (a gripper closed by a ramp, then rolled).
struct UniformFieldSchedule {
  std::vector<std::pair<double, Vec3>> keyframes;  ///< (t [s], B [T]), t increasing; empty: none (unless rotating)
  bool rotating = false;
  double amplitude = 0.0;       ///< [T]
  double frequency = 0.0;       ///< [Hz]
  Vec3 axis = Vec3::UnitX();    ///< unit rotation axis
  Vec3 start = Vec3::UnitZ();   ///< unit direction at t = rotation_start, ⟂ axis
  double rotation_start = 0.0;  ///< [s] when the rotation takes over from the keyframes

  /// B at time t [T].
  Vec3 at(double t) const;
  /// Whether any field is applied.
  bool any() const { return rotating || !keyframes.empty(); }
};

}  // namespace magvine::magnetics
