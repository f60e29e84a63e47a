// Topology and geometry diagnostics against meshes whose answers are known by construction: open and closed tubes,
// a torus (genus 1), two disjoint tubes, a non-manifold fin, mixed windings and inward normals.

#include <gtest/gtest.h>

#include <cmath>

#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

constexpr double kRoundoff = 1e-12;  // relative, sums of ~1e4 terms

// Torus of major radius R, minor r, (n × m) quads: closed, genus 1.
TriangleMesh make_torus(double big, double small, int n, int m) {
  TriangleMesh mesh;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double u = 2.0 * kPi * i / n, v = 2.0 * kPi * j / m;
      mesh.vertices.emplace_back((big + small * std::cos(v)) * std::cos(u), (big + small * std::cos(v)) * std::sin(u),
                                 small * std::sin(v));
    }
  }
  auto at = [n, m](int i, int j) { return static_cast<std::uint32_t>(((i + n) % n) * m + (j + m) % m); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return mesh;
}

void append(TriangleMesh& to, const TriangleMesh& from, const Vec3& shift) {
  const auto base = static_cast<std::uint32_t>(to.vertices.size());
  for (const Vec3& p : from.vertices) to.vertices.push_back(p + shift);
  for (const Triangle& t : from.triangles) to.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

TEST(MeshReport, ClosedTubeIsWatertightGenusZeroOutward) {
  const TubeSpec spec{.radius = 5e-3, .length = 0.06, .segments = 48, .rings = 0, .capped = true};
  const TriangleMesh tube = make_tube(spec);
  const MeshReport r = analyse_mesh(tube);
  EXPECT_EQ(r.triangles, tube.triangles.size());
  EXPECT_EQ(r.vertices, tube.vertices.size());
  EXPECT_TRUE(r.watertight);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_EQ(r.non_manifold_edges, 0u);
  EXPECT_EQ(r.components, 1u);
  EXPECT_EQ(r.genus, 0);
  EXPECT_EQ(r.orientation, Orientation::kOutward);
  ASSERT_TRUE(r.volume.has_value());
  EXPECT_NEAR(*r.volume, signed_volume(tube), kRoundoff * *r.volume);
  EXPECT_TRUE(r.openings.empty());
  EXPECT_TRUE(r.warnings.empty());
}

TEST(MeshReport, OpenTubeHasTwoOpeningsWithAxisNormalsAndPolygonDiameter) {
  const TubeSpec spec{.radius = 5e-3, .length = 0.06, .segments = 64, .rings = 0, .capped = false};
  const MeshReport r = analyse_mesh(make_tube(spec));
  EXPECT_FALSE(r.watertight);
  EXPECT_EQ(r.boundary_edges, 128u);
  EXPECT_FALSE(r.volume.has_value());
  EXPECT_EQ(r.genus, 0);  // an annulus: χ = 0 = 2·1 − 2g − 2
  EXPECT_EQ(r.orientation, Orientation::kOutward);  // decided with the openings capped
  ASSERT_EQ(r.openings.size(), 2u);
  // Equivalent diameter of the regular 64-gon: area n/2 R² sin(2π/n).
  const double n = spec.segments;
  const double d = 2.0 * std::sqrt(0.5 * n * spec.radius * spec.radius * std::sin(2.0 * kPi / n) / kPi);
  for (const Opening& o : r.openings) {
    EXPECT_NEAR(o.diameter, d, kRoundoff * d);
    EXPECT_EQ(o.edges, 64u);
    EXPECT_NEAR(o.centroid.x(), 0.0, 1e-15);
    EXPECT_NEAR(o.centroid.y(), 0.0, 1e-15);
    // Normals point out of the tube through the hole: −z at the bottom end, +z at the top.
    const double expected_z = o.centroid.z() < 0.5 * spec.length ? -1.0 : 1.0;
    EXPECT_NEAR(o.normal.z(), expected_z, 1e-12);
    EXPECT_NEAR(std::abs(o.centroid.z() - 0.5 * spec.length), 0.5 * spec.length, 1e-15);
  }
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings.front().find("open mesh"), std::string::npos);
}

TEST(MeshReport, TorusHasGenusOne) {
  const MeshReport r = analyse_mesh(make_torus(0.02, 0.005, 40, 16));
  EXPECT_TRUE(r.watertight);
  EXPECT_EQ(r.genus, 1);
  EXPECT_EQ(r.components, 1u);
  EXPECT_EQ(r.orientation, Orientation::kOutward);
}

TEST(MeshReport, TwoTubesAreTwoComponentsAndTwoTorusHandlesGenusTwo) {
  TriangleMesh mesh = make_tube({.radius = 5e-3, .length = 0.05, .segments = 32, .rings = 0, .capped = true});
  append(mesh, make_tube({.radius = 3e-3, .length = 0.02, .segments = 16, .rings = 0, .capped = true}),
         Vec3(0.05, 0, 0));
  MeshReport r = analyse_mesh(mesh);
  EXPECT_EQ(r.components, 2u);
  EXPECT_EQ(r.genus, 0);
  EXPECT_TRUE(r.watertight);
  EXPECT_EQ(r.warnings.size(), 1u);

  TriangleMesh tori = make_torus(0.02, 0.005, 40, 16);
  append(tori, make_torus(0.02, 0.005, 40, 16), Vec3(0.1, 0, 0));
  r = analyse_mesh(tori);
  EXPECT_EQ(r.components, 2u);
  EXPECT_EQ(r.genus, 2);  // genus sums over components
}

TEST(MeshReport, FinIsNonManifold) {
  // Three triangles on one edge (0, 1).
  TriangleMesh fin;
  fin.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  fin.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const MeshReport r = analyse_mesh(fin);
  EXPECT_EQ(r.non_manifold_edges, 1u);
  EXPECT_FALSE(r.watertight);
  EXPECT_EQ(r.boundary_edges, 6u);
}

TEST(MeshReport, MixedWindingIsInconsistentAndAllFlippedIsInward) {
  TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.05, .segments = 32, .rings = 0, .capped = true});
  flip_orientation(tube);
  MeshReport r = analyse_mesh(tube);
  EXPECT_EQ(r.orientation, Orientation::kInward);
  std::swap(tube.triangles[5][1], tube.triangles[5][2]);
  r = analyse_mesh(tube);
  EXPECT_EQ(r.orientation, Orientation::kInconsistent);
  EXPECT_TRUE(r.watertight);  // still closed; only the winding is wrong
}

TEST(MeshReport, AreaAndBoundingBoxMatchTheMeshFunctions) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.05, .segments = 32, .rings = 0, .capped = true});
  const MeshReport r = analyse_mesh(tube);
  EXPECT_NEAR(r.area, surface_area(tube), kRoundoff * r.area);
  EXPECT_EQ(r.bbox.max, bounding_box(tube).max);
}

TEST(MeshReport, EmptyMeshReportsZeros) {
  const MeshReport r = analyse_mesh(TriangleMesh{});
  EXPECT_EQ(r.triangles, 0u);
  EXPECT_EQ(r.components, 0u);
  EXPECT_FALSE(r.watertight);
}

}  // namespace
}  // namespace magvine::anatomy
