#include "magvine/anatomy/edge_bends.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace magvine::anatomy {
namespace {

/// Bends whose sine is below this are coplanar up to rounding (unit normals from cross products agree to ~1e-16).
constexpr double kFlatSine = 1e-10;

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

double EdgeBend::angle() const { return std::atan2(sin, cos); }

VertexTriangles vertex_triangles(const TriangleMesh& mesh) {
  const std::size_t n = mesh.triangles.size();
  const std::size_t nv = mesh.vertices.size();
  VertexTriangles out;
  out.normals.resize(n);
  for (std::size_t t = 0; t < n; ++t) out.normals[t] = unit_normal(mesh, mesh.triangles[t]);
  out.first.assign(nv + 1, 0);
  for (std::size_t t = 0; t < n; ++t) {
    if (out.normals[t].isZero()) continue;
    for (const std::uint32_t v : mesh.triangles[t]) ++out.first[v + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) out.first[v + 1] += out.first[v];
  out.triangles.resize(out.first[nv]);
  std::vector<std::uint32_t> fill(out.first.begin(), out.first.end() - 1);
  for (std::size_t t = 0; t < n; ++t) {
    if (out.normals[t].isZero()) continue;
    for (const std::uint32_t v : mesh.triangles[t]) out.triangles[fill[v]++] = static_cast<std::uint32_t>(t);
  }
  return out;
}

std::vector<std::array<EdgeBend, 3>> edge_bends(const TriangleMesh& mesh) {
  return edge_bends(mesh, vertex_triangles(mesh));
}

std::vector<std::array<EdgeBend, 3>> edge_bends(const TriangleMesh& mesh, const VertexTriangles& incidence) {
  const std::size_t n = mesh.triangles.size();
  const std::vector<Vec3>& normals = incidence.normals;
  const std::vector<std::uint32_t>& first = incidence.first;
  const std::vector<std::uint32_t>& incident = incidence.triangles;

  std::vector<std::array<EdgeBend, 3>> bends(n);
  for (std::size_t t = 0; t < n; ++t) {
    if (normals[t].isZero()) continue;
    const Triangle& tri = mesh.triangles[t];
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t a = tri[k];
      const std::uint32_t b = tri[(k + 1) % 3];
      // The other triangles at a that also contain b: exactly one for a manifold edge; otherwise a boundary.
      std::size_t found = 0;
      std::uint32_t u = 0;
      std::size_t ku = 0;  // u's corner at a
      for (std::uint32_t i = first[a]; i < first[a + 1]; ++i) {
        const std::uint32_t other = incident[i];
        if (other == t) continue;
        const Triangle& o = mesh.triangles[other];
        if (o[0] != b && o[1] != b && o[2] != b) continue;
        ++found;
        u = other;
        ku = o[0] == a ? 0 : o[1] == a ? 1 : 2;
      }
      if (found != 1) continue;
      const Triangle& o = mesh.triangles[u];
      const Vec3& nt = normals[t];
      // The neighbour's normal as if it were oriented like t: a consistently oriented neighbour runs the shared
      // edge b → a, i.e. its corner after a is not b.
      const bool reversed = o[(ku + 1) % 3] != b;
      const Vec3 nu = reversed ? normals[u] : Vec3(-normals[u]);
      const double sine = nt.cross(nu).norm();
      const std::uint32_t c = o[0] != a && o[0] != b ? o[0] : o[1] != a && o[1] != b ? o[1] : o[2];
      EdgeBend& bend = bends[t][k];
      bend.boundary = false;
      bend.neighbour = u;
      if (sine >= kFlatSine || nt.dot(nu) < 0.0) {
        bend.cos = nt.dot(nu);
        bend.sin = sine;
      }
      bend.convex = nt.dot(mesh.vertices[c] - mesh.vertices[a]) < 0.0;  // c: the neighbour's corner off the edge
    }
  }
  return bends;
}

}  // namespace magvine::anatomy
