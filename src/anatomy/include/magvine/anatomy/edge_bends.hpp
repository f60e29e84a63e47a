#pragma once
/// How the surface bends across each triangle edge, from the welded index buffer: the data behind snag-free
/// contacts (the same quantities Bullet's btGenerateInternalEdgeInfo stores in a btTriangleInfoMap, which a test
/// compares against; computed here from vertex–triangle incidence in linear time, instead of Bullet's one box query
/// per triangle, which took 10 s on a 1 M-triangle mesh).

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// The bend across one edge of a triangle t, seen from t.
struct EdgeBend {
  /// Cosine and sine of the angle between t's normal and its neighbour's, in [0, π] (sin ≥ 0); exactly (1, 0) when
  /// coplanar. Kept as the pair the contact code uses, so no angle is computed per edge.
  double cos = 1.0;
  double sin = 0.0;
  bool convex = false;          ///< the neighbour falls away behind t's plane (convex seen from the outward normals)
  bool boundary = true;         ///< no neighbour to bend to: an open rim, a non-manifold edge or a zero-area neighbour
  std::uint32_t neighbour = 0;  ///< the triangle across the edge (when not a boundary)

  /// The bend angle [rad], in [0, π].
  double angle() const;
};

/// Vertex → incident triangles (compressed rows): the triangles at vertex v are
/// triangles[first[v]] … triangles[first[v + 1] − 1], in increasing order. Zero-area triangles are left out.
struct VertexTriangles {
  std::vector<std::uint32_t> first;      ///< vertices + 1 offsets
  std::vector<std::uint32_t> triangles;  ///< triangle indices
  std::vector<Vec3> normals;             ///< unit normal of every triangle (outward), zero for zero-area ones
};
VertexTriangles vertex_triangles(const TriangleMesh& mesh);

/// Unit normal of the triangle (a, b, c), or zero when its area is below 1e-12 of its longest edge squared (no
/// direction survives rounding).
Vec3 triangle_unit_normal(const Vec3& a, const Vec3& b, const Vec3& c);

/// The bend across edge k (corner k → corner k + 1) of triangle `tri` (unit normal `nt`) to its neighbour `u` across
/// that edge (corners `o`, unit normal `nu` as u is oriented): the one law behind edge_bends(), also used to bring
/// one triangle's bends up to date after its vertices moved (CollisionWorld::refit).
EdgeBend bend_across(std::span<const Vec3> vertices, const Triangle& tri, std::size_t k, const Vec3& nt,
                     std::uint32_t u, const Triangle& o, const Vec3& nu);

/// Bends of edge k (corner k → corner k + 1) of every triangle. Bends with sin below 1e-10 are coplanar (up to
/// rounding). Zero-area triangles have no normal: their own entries are boundary and they are nobody's neighbour.
std::vector<std::array<EdgeBend, 3>> edge_bends(const TriangleMesh& mesh);
/// The same with the mesh's vertex_triangles() already at hand.
std::vector<std::array<EdgeBend, 3>> edge_bends(const TriangleMesh& mesh, const VertexTriangles& incidence);

}  // namespace magvine::anatomy
