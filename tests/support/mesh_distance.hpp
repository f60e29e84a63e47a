#pragma once
// A test reference for distances to a triangle mesh: every triangle checked, no BVH. Exact unsigned distances from
// a point or a segment to the mesh with the closest points, by the closed-form point–triangle closest point
// (Ericson 5.1.5, segment_geometry.hpp) and segment–triangle distance (a crossing, else an endpoint or an edge in
// the closest pair). Triangles whose centroid ball lies farther than the best distance so far are skipped, which
// is exact (the ball holds the triangle) and keeps a 200 k-triangle airway at about a millisecond per query.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "magvine/anatomy/segment_geometry.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::test {

/// The nearest point of a mesh to a point or a segment.
struct MeshNearest {
  double distance = std::numeric_limits<double>::infinity();  ///< [m], ≥ 0
  Vec3 on_mesh = Vec3::Zero();                                ///< closest point on the mesh [m]
  Vec3 on_query = Vec3::Zero();                               ///< closest point on the query point or segment [m]
};

class BruteForceDistance {
 public:
  explicit BruteForceDistance(const anatomy::TriangleMesh& mesh) : m_mesh(mesh) {
    for (const anatomy::Triangle& t : mesh.triangles) {
      const Vec3 c = (corner(t, 0) + corner(t, 1) + corner(t, 2)) / 3.0;
      double bound = 0.0;
      for (int k = 0; k < 3; ++k) bound = std::max(bound, (corner(t, k) - c).norm());
      m_centroid.push_back(c);
      m_bound.push_back(bound * (1.0 + 1e-12));
    }
  }

  MeshNearest point(const Vec3& p) const {
    MeshNearest best;
    for (std::size_t i = 0; i < m_mesh.triangles.size(); ++i) {
      if ((m_centroid[i] - p).norm() - m_bound[i] > best.distance) continue;
      const anatomy::Triangle& t = m_mesh.triangles[i];
      const Vec3 q = anatomy::closest_point_on_triangle(p, corner(t, 0), corner(t, 1), corner(t, 2));
      const double d = (q - p).norm();
      if (d < best.distance) best = {d, q, p};
    }
    return best;
  }

  MeshNearest segment(const Vec3& a, const Vec3& b) const {
    MeshNearest best;
    for (std::size_t i = 0; i < m_mesh.triangles.size(); ++i) {
      const Vec3 near = anatomy::closest_point_on_segment(m_centroid[i], a, b);
      if ((m_centroid[i] - near).norm() - m_bound[i] > best.distance) continue;
      const anatomy::Triangle& t = m_mesh.triangles[i];
      Vec3 on_segment;
      Vec3 on_triangle;
      const double d =
          std::sqrt(segment_triangle_sq(a, b, corner(t, 0), corner(t, 1), corner(t, 2), on_segment, on_triangle));
      if (d < best.distance) best = {d, on_triangle, on_segment};
    }
    return best;
  }

 private:
  const Vec3& corner(const anatomy::Triangle& t, int k) const {
    return m_mesh.vertices[t[static_cast<std::size_t>(k)]];
  }

  /// Squared distance between the segment a–b and the triangle p0 p1 p2, with the closest points. A segment that
  /// crosses the triangle is at distance 0 there; otherwise the closest pair has a segment endpoint or a triangle
  /// edge in it (an interior–interior minimum needs the segment parallel to the plane, and sliding along it then
  /// reaches an endpoint or an edge at the same distance).
  static double segment_triangle_sq(const Vec3& a, const Vec3& b, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                                    Vec3& on_segment, Vec3& on_triangle) {
    const Vec3 n = (p1 - p0).cross(p2 - p0);
    const double da = n.dot(a - p0);
    const double db = n.dot(b - p0);
    if (((da <= 0.0 && db >= 0.0) || (da >= 0.0 && db <= 0.0)) && da != db) {
      const Vec3 x = a + (b - a) * (da / (da - db));
      if (n.dot((p1 - p0).cross(x - p0)) >= 0.0 && n.dot((p2 - p1).cross(x - p1)) >= 0.0 &&
          n.dot((p0 - p2).cross(x - p2)) >= 0.0) {
        on_segment = on_triangle = x;
        return 0.0;
      }
    }
    double best = std::numeric_limits<double>::infinity();
    const Vec3* corners[3] = {&p0, &p1, &p2};
    for (int i = 0; i < 3; ++i) {
      const Vec3& e0 = *corners[i];
      const Vec3& e1 = *corners[(i + 1) % 3];
      const anatomy::SegmentParameters c = anatomy::closest_segment_parameters(a, b - a, e0, e1 - e0);
      const Vec3 u = a + (b - a) * c.s;
      const Vec3 w = e0 + (e1 - e0) * c.t;
      const double d = (u - w).squaredNorm();
      if (d < best) {
        best = d;
        on_segment = u;
        on_triangle = w;
      }
    }
    for (const Vec3* e : {&a, &b}) {
      const Vec3 c = anatomy::closest_point_on_triangle(*e, p0, p1, p2);
      const double d = (c - *e).squaredNorm();
      if (d < best) {
        best = d;
        on_segment = *e;
        on_triangle = c;
      }
    }
    return best;
  }

  const anatomy::TriangleMesh& m_mesh;
  std::vector<Vec3> m_centroid;
  std::vector<double> m_bound;
};

}  // namespace magvine::test
