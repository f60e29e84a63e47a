// edge_bends() against Bullet's own btGenerateInternalEdgeInfo (the btTriangleInfoMap the collision world used to
// build, now the independent reference): the same bend angle, convexity and boundary for every edge of a tube, a
// folded sheet and a real airway.

#include "magvine/anatomy/edge_bends.hpp"

#include <BulletCollision/CollisionDispatch/btInternalEdgeUtility.h>
#include <BulletCollision/CollisionShapes/btTriangleInfoMap.h>
#include <btBulletCollisionCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/units.hpp"
#include "support/airways.hpp"

namespace magvine::anatomy {
namespace {

/// Compares every edge with Bullet's triangle info map of the same mesh; returns the number of bent edges seen.
int expect_same_as_bullet(const TriangleMesh& mesh) {
  btIndexedMesh part;
  part.m_numTriangles = static_cast<int>(mesh.triangles.size());
  part.m_triangleIndexBase = reinterpret_cast<const unsigned char*>(mesh.triangles.data());
  part.m_triangleIndexStride = static_cast<int>(sizeof(Triangle));
  part.m_numVertices = static_cast<int>(mesh.vertices.size());
  part.m_vertexBase = reinterpret_cast<const unsigned char*>(mesh.vertices.data());
  part.m_vertexStride = static_cast<int>(sizeof(Vec3));
  part.m_vertexType = PHY_DOUBLE;
  btTriangleIndexVertexArray mesh_interface;
  mesh_interface.addIndexedMesh(part, PHY_INTEGER);
  btBvhTriangleMeshShape shape(&mesh_interface, true, true);
  btTriangleInfoMap map;
  // Bullet's thresholds are in game units; the mesh is indexed, so they only need to be positive and tiny.
  const Aabb box = bounding_box(mesh);
  map.m_equalVertexThreshold = std::pow(1e-12 * (box.max - box.min).norm(), 2) + std::numeric_limits<double>::min();
  map.m_zeroAreaThreshold = map.m_equalVertexThreshold;
  map.m_planarEpsilon = 1e-20;  // sin² of the bend: bends below 1e-10 rad are flat, as in edge_bends
  btGenerateInternalEdgeInfo(&shape, &map);

  const auto bends = edge_bends(mesh);
  constexpr int kConvex[3] = {TRI_INFO_V0V1_CONVEX, TRI_INFO_V1V2_CONVEX, TRI_INFO_V2V0_CONVEX};
  // Both compute the angle between unit normals of the same coordinates, Bullet with acos-type formulas that lose
  // digits near 0 and π: 1e-7 rad is far below any bend that matters (1e-3 rad on these meshes) yet catches a
  // wrong neighbour or a sign error, which cost O(0.1) rad.
  constexpr double kAngleTol = 1e-7;
  int bent = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const btTriangleInfo* info = map.find(btHashInt(static_cast<int>(t)));
    for (int k = 0; k < 3; ++k) {
      const double angle = info == nullptr ? SIMD_2_PI
                           : k == 0        ? info->m_edgeV0V1Angle
                           : k == 1        ? info->m_edgeV1V2Angle
                                           : info->m_edgeV2V0Angle;
      const EdgeBend& ours = bends[t][static_cast<std::size_t>(k)];
      EXPECT_EQ(ours.boundary, angle == SIMD_2_PI) << "triangle " << t << " edge " << k;
      if (ours.boundary || angle == SIMD_2_PI) continue;
      EXPECT_NEAR(ours.angle(), std::abs(angle), kAngleTol) << "triangle " << t << " edge " << k;
      if (ours.angle() > 1e-6) {
        ++bent;
        EXPECT_EQ(ours.convex, (info->m_flags & kConvex[k]) != 0) << "triangle " << t << " edge " << k;
      }
    }
  }
  return bent;
}

TEST(EdgeBends, TubeMatchesBullet) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 50e-3, .segments = 64});
  EXPECT_GT(expect_same_as_bullet(tube), 1000);
  // Every bend of a closed convex prism is convex from outside: 2π/64 between strips, π/2 at the rims.
  for (const auto& edges : edge_bends(tube)) {
    for (const EdgeBend& e : edges) {
      EXPECT_FALSE(e.boundary);
      if (e.angle() > 0.0) {
        EXPECT_TRUE(e.convex);
      }
    }
  }
}

TEST(EdgeBends, OpenTubeHasBoundaryRims) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 50e-3, .segments = 32, .capped = false});
  expect_same_as_bullet(tube);
  int boundary = 0;
  for (const auto& edges : edge_bends(tube)) {
    for (const EdgeBend& e : edges) boundary += e.boundary ? 1 : 0;
  }
  EXPECT_EQ(boundary, 2 * 32);  // two rims of 32 edges
}

TEST(EdgeBends, RealAirwayMatchesBullet) {
  const auto file = test::airway_file("siliconmodel3_airway.stl");
  if (!file) GTEST_SKIP() << "../shared/airways absent";
  const TriangleMesh mesh = import_mesh(*file, {.units = LengthUnit::kMm}).mesh;
  EXPECT_GT(expect_same_as_bullet(mesh), 100000);
}

}  // namespace
}  // namespace magvine::anatomy
