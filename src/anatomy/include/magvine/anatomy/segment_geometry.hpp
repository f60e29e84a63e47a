#pragma once
/// Closest points of segments and triangles, shared by the contact, distance and phantom code and the robot's wall
/// barrier.

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

/// Closest point to p on triangle abc: Ericson, Real-Time Collision Detection (2005), §5.1.5, by Voronoi regions of
/// the vertices, then the edges, then the face. A zero-area triangle (collinear corners) never reaches the face
/// region with a positive denominator; it falls back to the closest of its three edges.
inline Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;  // vertex a
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;  // vertex b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + ab * (d1 / (d1 - d3));  // edge ab
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;  // vertex c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + ac * (d2 / (d2 - d6));  // edge ac
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));  // bc
  const double sum = va + vb + vc;  // = |ab × ac|², zero only for a degenerate triangle
  if (!(sum > 0.0)) {
    Vec3 best = closest_point_on_segment(p, a, b);
    for (const Vec3& q : {closest_point_on_segment(p, b, c), closest_point_on_segment(p, c, a)}) {
      if ((q - p).squaredNorm() < (best - p).squaredNorm()) best = q;
    }
    return best;
  }
  return a + ab * (vb / sum) + ac * (vc / sum);  // face, barycentric (u, v, w) = (va, vb, vc)/sum
}

/// Distance between the segments p1–q1 and p2–q2 [m].
inline double segment_distance(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const SegmentParameters c = closest_segment_parameters(p1, q1 - p1, p2, q2 - p2);
  return (p1 + c.s * (q1 - p1) - p2 - c.t * (q2 - p2)).norm();
}

}  // namespace magvine::anatomy
