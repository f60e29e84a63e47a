// Welding and cleaning on meshes with known answers: a tube exploded into per-triangle corners (as STL stores it),
// jittered copies below and above the weld tolerance, and determinism of the vertex order.

#include <gtest/gtest.h>

#include "magvine/anatomy/mesh_clean.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/primitives.hpp"

namespace magvine::anatomy {
namespace {

TriangleMesh explode(const TriangleMesh& mesh) {
  TriangleMesh soup;
  for (const Triangle& t : mesh.triangles) {
    const auto base = static_cast<std::uint32_t>(soup.vertices.size());
    for (const std::uint32_t v : t) soup.vertices.push_back(mesh.vertices[v]);
    soup.triangles.push_back({base, base + 1, base + 2});
  }
  return soup;
}

TEST(MeshClean, ExplodedTubeWeldsBackToTheIndexedTube) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.03, .segments = 32, .rings = 0, .capped = true});
  TriangleMesh soup = explode(tube);
  const CleanStats stats = weld_and_clean(soup);
  EXPECT_EQ(soup.vertices.size(), tube.vertices.size());
  EXPECT_EQ(stats.vertices_welded, 3 * tube.triangles.size() - tube.vertices.size());
  EXPECT_EQ(stats.degenerate_removed, 0u);
  EXPECT_EQ(stats.duplicate_removed, 0u);
  EXPECT_TRUE(analyse_mesh(soup).watertight);
}

TEST(MeshClean, JitterBelowToleranceWeldsAboveDoesNot) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.03, .segments = 16, .rings = 4, .capped = false});
  TriangleMesh soup = explode(tube);
  TriangleMesh far = soup;
  // The grid pitch is the tolerance; a shift of 1 % of it almost never crosses a cell boundary for these
  // coordinates, a shift of 10 pitches always leaves the cell.
  const double tol = 1e-9;
  for (std::size_t i = 0; i < soup.vertices.size(); i += 3) soup.vertices[i].x() += 0.01 * tol;
  for (std::size_t i = 0; i < far.vertices.size(); i += 3) far.vertices[i].x() += 10.0 * tol;
  weld_and_clean(soup, tol);
  weld_and_clean(far, tol);
  EXPECT_EQ(analyse_mesh(soup).boundary_edges, analyse_mesh(tube).boundary_edges);
  EXPECT_GT(analyse_mesh(far).boundary_edges, analyse_mesh(tube).boundary_edges);
}

TEST(MeshClean, ResultIsDeterministicAndFollowsFirstUse) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.03, .segments = 12, .rings = 3, .capped = true});
  TriangleMesh a = explode(tube), b = explode(tube);
  weld_and_clean(a);
  weld_and_clean(b);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.triangles.front(), (Triangle{0, 1, 2}));
}

TEST(MeshClean, EmptyMeshAndUnusedVertices) {
  TriangleMesh lonely;
  lonely.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const CleanStats stats = weld_and_clean(lonely);
  EXPECT_EQ(stats.unused_removed, 2u);
  EXPECT_TRUE(lonely.vertices.empty());
}

/// An axis-aligned box [m] as 12 triangles, normals outward (or inward with `inward`).
void add_box(TriangleMesh& mesh, const Vec3& lo, const Vec3& hi, bool inward = false) {
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (int c = 0; c < 8; ++c) {
    mesh.vertices.emplace_back((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
  }
  const std::array<Triangle, 12> faces{{{0, 2, 1},
                                        {1, 2, 3},
                                        {4, 5, 6},
                                        {5, 7, 6},
                                        {0, 1, 4},
                                        {1, 5, 4},
                                        {2, 6, 3},
                                        {3, 6, 7},
                                        {0, 4, 2},
                                        {2, 4, 6},
                                        {1, 3, 5},
                                        {3, 7, 5}}};
  for (Triangle f : faces) {
    if (inward) std::swap(f[1], f[2]);
    mesh.triangles.push_back({base + f[0], base + f[1], base + f[2]});
  }
}

// A 10 mm box with a 2 mm cavity inside (inward normals) and a 1 mm box beside it: the big box stays, the cavity and
// the fragment are counted with their exact volumes, and their vertices go with them.
TEST(MeshClean, KeepLargestComponentDropsCavitiesAndFragments) {
  TriangleMesh mesh;
  add_box(mesh, Vec3(0.004, 0.004, 0.004), Vec3(0.006, 0.006, 0.006), true);
  add_box(mesh, Vec3::Zero(), Vec3::Constant(0.010));
  add_box(mesh, Vec3::Constant(0.020), Vec3::Constant(0.021));
  TriangleMesh big;
  add_box(big, Vec3::Zero(), Vec3::Constant(0.010));
  ASSERT_NEAR(signed_volume(big), 1e-6, 1e-18);
  const DroppedParts dropped = keep_largest_component(mesh);
  EXPECT_EQ(dropped.cavities, 1u);
  EXPECT_EQ(dropped.fragments, 1u);
  EXPECT_NEAR(dropped.cavity_volume, 8e-9, 1e-20);
  EXPECT_NEAR(dropped.fragment_volume, 1e-9, 1e-20);
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_EQ(mesh.vertices.size(), 8u);
  EXPECT_NEAR(signed_volume(mesh), 1e-6, 1e-18);
}

}  // namespace
}  // namespace magvine::anatomy
