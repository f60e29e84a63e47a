#pragma once
/// Closest points of two segments, shared by the contact, distance and phantom code.

#include <algorithm>
#include <limits>

#include "magvine/core/eigen_types.hpp"

namespace magvine::anatomy {

/// Parameters of the closest points p0 + s·u and q0 + t·v, s, t ∈ [0, 1].
struct SegmentParameters {
  double s = 0.0;
  double t = 0.0;
};

/// Closest points of the segments p0 + s·u and q0 + t·v: Ericson, Real-Time Collision Detection (2005) §5.1.9,
/// minimising |p0 + s·u − q0 − t·v|² over [0, 1]² by clamping s, then t, then s again. A zero vector is a point;
/// (near-)parallel segments (u × v below 1e-7 relative) take s = 0 first.
inline SegmentParameters closest_segment_parameters(const Vec3& p0, const Vec3& u, const Vec3& q0, const Vec3& v) {
  constexpr double kTiny = std::numeric_limits<double>::min();
  const Vec3 r = p0 - q0;
  const double a = u.squaredNorm();
  const double e = v.squaredNorm();
  const double f = v.dot(r);
  if (a <= kTiny && e <= kTiny) return {};
  if (a <= kTiny) return {0.0, std::clamp(f / e, 0.0, 1.0)};
  const double c = u.dot(r);
  if (e <= kTiny) return {std::clamp(-c / a, 0.0, 1.0), 0.0};
  const double b = u.dot(v);
  const double denom = a * e - b * b;  // |u × v|² ≥ 0
  double s = denom > 1e-14 * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1.0) {
    t = 1.0;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
  return {s, t};
}

/// Closest point to p on the segment a–b (a = b allowed).
inline Vec3 closest_point_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 d = b - a;
  const double dd = d.squaredNorm();
  if (dd <= 0.0) return a;
  return a + d * std::clamp((p - a).dot(d) / dd, 0.0, 1.0);
}

/// Distance between the segments p1–q1 and p2–q2 [m].
inline double segment_distance(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const SegmentParameters c = closest_segment_parameters(p1, q1 - p1, p2, q2 - p2);
  return (p1 + c.s * (q1 - p1) - p2 - c.t * (q2 - p2)).norm();
}

}  // namespace magvine::anatomy
