#pragma once
/// The indexed triangle mesh every anatomy component shares: vertices in metres (world frame), triangles as
/// vertex-index triples. The layout is plain and contiguous so FCL and Embree's builder can read it without copies.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::anatomy {

/// Vertex indices of one triangle; counter-clockwise seen from the side its normal points to.
using Triangle = std::array<std::uint32_t, 3>;

/// Indexed triangle mesh [m]. For a closed airway lumen the triangles are oriented so that normals point out of
/// the lumen (into tissue) when `signed_volume(mesh) > 0`.
struct TriangleMesh {
  std::vector<Vec3> vertices;       ///< N vertices, world frame [m]
  std::vector<Triangle> triangles;  ///< M triangles, indices into `vertices`
};

/// Axis-aligned bounding box [m].
struct Aabb {
  Vec3 min = Vec3::Constant(0.0);
  Vec3 max = Vec3::Constant(0.0);
};

/// Corner k (0, 1, 2) of triangle t.
inline const Vec3& corner(const TriangleMesh& mesh, std::size_t t, int k) {
  return mesh.vertices[mesh.triangles[t][static_cast<std::size_t>(k)]];
}

/// Twice-area vector (b − a) × (c − a) of triangle t [m²]: normal direction by the right-hand rule.
inline Vec3 area_vector(const TriangleMesh& mesh, std::size_t t) {
  const Vec3& a = corner(mesh, t, 0);
  return (corner(mesh, t, 1) - a).cross(corner(mesh, t, 2) - a);
}

/// Total surface area [m²].
double surface_area(const TriangleMesh& mesh);

/// Enclosed volume by the divergence theorem [m³]: Σ a·(b × c)/6. Meaningful for closed meshes; positive when the
/// triangles are oriented with outward normals.
double signed_volume(const TriangleMesh& mesh);

/// Bounding box of the vertices actually used by triangles [m]; zero box for an empty mesh.
Aabb bounding_box(const TriangleMesh& mesh);

/// Reverses every triangle's winding (flips all normals).
void flip_orientation(TriangleMesh& mesh);

/// Throws InputError("<who>: ...") for a mesh no query structure can be built on: no triangles, a non-finite
/// vertex, or a triangle index out of range.
void validate_mesh(const TriangleMesh& mesh, const std::string& who);

}  // namespace magvine::anatomy
