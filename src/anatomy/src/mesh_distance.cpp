#include "magvine/anatomy/mesh_distance.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace magvine::anatomy {

namespace {

double distance_to(const CollisionWorld& to, const Vec3& p) {
  std::array<NearTriangle, 1> nearest;
  for (double radius = 1e-3;; radius *= 2.0) {
    if (to.triangles_within(p, radius, nearest) > 0) return nearest[0].distance;
  }
}

}  // namespace

SurfaceDistance surface_distance(const TriangleMesh& from, const CollisionWorld& to) {
  SurfaceDistance d;
  double weight = 0.0, sum = 0.0, sum2 = 0.0;
  for (std::size_t t = 0; t < from.triangles.size(); ++t) {
    const double area = 0.5 * area_vector(from, t).norm();
    const Vec3 c = (corner(from, t, 0) + corner(from, t, 1) + corner(from, t, 2)) / 3.0;
    const std::array<std::pair<Vec3, double>, 4> samples{
        {{c, 0.5}, {corner(from, t, 0), 1.0 / 6.0}, {corner(from, t, 1), 1.0 / 6.0}, {corner(from, t, 2), 1.0 / 6.0}}};
    for (const auto& [p, share] : samples) {
      const double dist = distance_to(to, p);
      sum += share * area * dist;
      sum2 += share * area * dist * dist;
      d.max = std::max(d.max, dist);
    }
    weight += area;
  }
  if (weight > 0.0) {
    d.mean = sum / weight;
    d.rms = std::sqrt(sum2 / weight);
  }
  return d;
}

SurfaceDistance symmetric_surface_distance(const TriangleMesh& a, const TriangleMesh& b) {
  const SurfaceDistance ab = surface_distance(a, CollisionWorld(b));
  const SurfaceDistance ba = surface_distance(b, CollisionWorld(a));
  return {0.5 * (ab.mean + ba.mean), std::sqrt(0.5 * (ab.rms * ab.rms + ba.rms * ba.rms)), std::max(ab.max, ba.max)};
}

}  // namespace magvine::anatomy
