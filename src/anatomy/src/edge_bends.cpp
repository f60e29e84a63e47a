#include "magvine/anatomy/edge_bends.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace magvine::anatomy {
namespace {

/// Bends whose sine is below this are coplanar up to rounding (unit normals from cross products agree to ~1e-16).
constexpr double kFlatSine = 1e-10;

Vec3 unit_normal(const TriangleMesh& mesh, const Triangle& t) {
  return triangle_unit_normal(mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]);
}

}  // namespace

Vec3 triangle_unit_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a);
  const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return n.norm() > 1e-12 * longest2 ? Vec3(n.normalized()) : Vec3(Vec3::Zero());
}

EdgeBend bend_across(std::span<const Vec3> vertices, const Triangle& tri, std::size_t k, const Vec3& nt,
                     std::uint32_t u, const Triangle& o, const Vec3& nu) {
  const std::uint32_t a = tri[k];
  const std::uint32_t b = tri[(k + 1) % 3];
  const std::size_t ku = o[0] == a ? 0 : o[1] == a ? 1 : 2;  // u's corner at a
  // The neighbour's normal as if it were oriented like t: a consistently oriented neighbour runs the shared edge
  // b → a, i.e. its corner after a is not b.
  const bool reversed = o[(ku + 1) % 3] != b;
  const Vec3 nr = reversed ? nu : Vec3(-nu);
  const double sine = nt.cross(nr).norm();
  const std::uint32_t c = o[0] != a && o[0] != b ? o[0] : o[1] != a && o[1] != b ? o[1] : o[2];
  EdgeBend bend;
  bend.boundary = false;
  bend.neighbour = u;
  if (sine >= kFlatSine || nt.dot(nr) < 0.0) {
    bend.cos = nt.dot(nr);
    bend.sin = sine;
  }
  bend.convex = nt.dot(vertices[c] - vertices[a]) < 0.0;  // c: the neighbour's corner off the edge
  return bend;
}

double EdgeBend::angle() const {
  return std::atan2(sin, cos);
}

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
      for (std::uint32_t i = first[a]; i < first[a + 1]; ++i) {
        const std::uint32_t other = incident[i];
        if (other == t) continue;
        const Triangle& o = mesh.triangles[other];
        if (o[0] != b && o[1] != b && o[2] != b) continue;
        ++found;
        u = other;
      }
      if (found != 1) continue;
      bends[t][k] = bend_across(mesh.vertices, tri, k, normals[t], u, mesh.triangles[u], normals[u]);
    }
  }
  return bends;
}

}  // namespace magvine::anatomy
