#include "magvine/anatomy/edge_bends.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace magvine::anatomy {
namespace {

/// Bends below this are coplanar up to rounding (unit normals from cross products agree to ~1e-16).
constexpr double kFlatAngle = 1e-10;

/// Unit normal of t, or zero when its area is below 1e-12 of its longest edge squared (no direction).
Vec3 unit_normal(const TriangleMesh& mesh, const Triangle& t) {
  const Vec3& a = mesh.vertices[t[0]];
  const Vec3& b = mesh.vertices[t[1]];
  const Vec3& c = mesh.vertices[t[2]];
  const Vec3 n = (b - a).cross(c - a);
  const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return n.norm() > 1e-12 * longest2 ? Vec3(n.normalized()) : Vec3(Vec3::Zero());
}

}  // namespace

std::vector<std::array<EdgeBend, 3>> edge_bends(const TriangleMesh& mesh) {
  const std::size_t n = mesh.triangles.size();
  std::vector<Vec3> normals(n);
  for (std::size_t t = 0; t < n; ++t) normals[t] = unit_normal(mesh, mesh.triangles[t]);

  // Every directed edge of a triangle with a normal, keyed by its undirected vertex pair; sorting groups the
  // triangles that share an edge.
  struct HalfEdge {
    std::uint64_t key;
    std::uint32_t triangle;
    std::uint32_t k;
  };
  std::vector<HalfEdge> edges;
  edges.reserve(3 * n);
  for (std::size_t t = 0; t < n; ++t) {
    if (normals[t].isZero()) continue;
    const Triangle& tri = mesh.triangles[t];
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint64_t a = tri[k];
      const std::uint64_t b = tri[(k + 1) % 3];
      edges.push_back({std::min(a, b) << 32 | std::max(a, b), static_cast<std::uint32_t>(t), k});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : x.triangle < y.triangle;
  });

  std::vector<std::array<EdgeBend, 3>> bends(n);
  const auto bend_from = [&](const HalfEdge& self, const HalfEdge& other) {
    const Triangle& t = mesh.triangles[self.triangle];
    const Triangle& u = mesh.triangles[other.triangle];
    const Vec3& nt = normals[self.triangle];
    // The neighbour's normal as if it were oriented like t: a consistently oriented neighbour runs the shared
    // edge the other way.
    const bool reversed = u[other.k] == t[(self.k + 1) % 3];
    const Vec3 nu = reversed ? normals[other.triangle] : Vec3(-normals[other.triangle]);
    const double angle = std::atan2(nt.cross(nu).norm(), nt.dot(nu));
    const Vec3& w = mesh.vertices[u[(other.k + 2) % 3]];  // the neighbour's corner off the edge
    EdgeBend& bend = bends[self.triangle][self.k];
    bend.boundary = false;
    bend.angle = angle < kFlatAngle ? 0.0 : angle;
    bend.convex = nt.dot(w - mesh.vertices[t[self.k]]) < 0.0;
  };
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    if (j - i == 2) {  // manifold: exactly two triangles; otherwise every side stays a boundary
      bend_from(edges[i], edges[i + 1]);
      bend_from(edges[i + 1], edges[i]);
    }
    i = j;
  }
  return bends;
}

}  // namespace magvine::anatomy
