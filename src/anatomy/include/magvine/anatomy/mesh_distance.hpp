#pragma once
/// How far apart two surfaces are: the figures an imported or remeshed surface is judged by against a reference
/// (ct import against the marching-cubes meshes, docs/ct.md).

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// Distances from the surface of one mesh to another [m].
struct SurfaceDistance {
  double mean = 0.0;  ///< area-weighted mean over the first mesh's surface
  double rms = 0.0;   ///< area-weighted root mean square
  double max = 0.0;   ///< largest, over the sample points
};

/// One-sided distance from `from` to the surface of `to`: each triangle's centroid and corners sampled, weighted by
/// a third of the triangle's area per sample group (centroid ½, corners ⅙ each), the exact point–triangle
/// distance to the nearest triangle of `to` (CollisionWorld::triangles_within, the search radius doubled from
/// 1 mm until a triangle is found).
SurfaceDistance surface_distance(const TriangleMesh& from, const CollisionWorld& to);

/// Symmetric: the mean and RMS of both one-sided figures averaged, the larger maximum.
SurfaceDistance symmetric_surface_distance(const TriangleMesh& a, const TriangleMesh& b);

}  // namespace magvine::anatomy
