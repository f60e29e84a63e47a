#include "magvine/anatomy/triangle_mesh.hpp"

#include <algorithm>
#include <limits>
#include <utility>

#include "magvine/core/error.hpp"

namespace magvine::anatomy {

double surface_area(const TriangleMesh& mesh) {
  double twice = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) twice += area_vector(mesh, t).norm();
  return 0.5 * twice;
}

double signed_volume(const TriangleMesh& mesh) {
  // Sum of signed tetrahedra (origin, a, b, c). Shift by the first vertex so that meshes far from the origin
  // (CT scanner coordinates sit ~1 m away) do not lose digits to cancellation.
  if (mesh.triangles.empty()) return 0.0;
  const Vec3 o = mesh.vertices[mesh.triangles.front()[0]];
  double six = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Vec3 a = corner(mesh, t, 0) - o, b = corner(mesh, t, 1) - o, c = corner(mesh, t, 2) - o;
    six += a.dot(b.cross(c));
  }
  return six / 6.0;
}

Aabb bounding_box(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) return {};
  Aabb box{Vec3::Constant(std::numeric_limits<double>::infinity()),
           Vec3::Constant(-std::numeric_limits<double>::infinity())};
  for (const Triangle& tri : mesh.triangles) {
    for (const std::uint32_t v : tri) {
      box.min = box.min.cwiseMin(mesh.vertices[v]);
      box.max = box.max.cwiseMax(mesh.vertices[v]);
    }
  }
  return box;
}

void flip_orientation(TriangleMesh& mesh) {
  for (Triangle& tri : mesh.triangles) std::swap(tri[1], tri[2]);
}

void validate_mesh(const TriangleMesh& mesh, const std::string& who) {
  if (mesh.triangles.empty()) throw InputError(who + ": the mesh has no triangles");
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!mesh.vertices[i].allFinite()) throw InputError(who + ": vertex " + std::to_string(i) + " is not finite");
  }
  const std::size_t n = mesh.vertices.size();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (const std::uint32_t v : mesh.triangles[t]) {
      if (v >= n) {
        throw InputError(who + ": triangle " + std::to_string(t) + " uses vertex " + std::to_string(v) +
                         ", allowed range [0, " + std::to_string(n) + ")");
      }
    }
  }
}

}  // namespace magvine::anatomy
