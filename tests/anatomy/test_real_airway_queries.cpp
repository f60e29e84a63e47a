// The collision world on real CT airways (../shared/airways; skipped when absent), each query against a method
// that shares no BVH or feature code with it:
//  * contains() (ray parity over the world's BVH) against the generalised winding number summed over every triangle
//    (Van Oosterom–Strackee solid angles, no BVH, no rays);
//  * sphere and capsule contacts (the world's narrow phase on its BVH) against the exact wall distance over every
//    triangle (support/mesh_distance.hpp: closest points by closed form, no BVH): for a sphere
//    of radius r centred in the lumen at distance d from the wall, the deepest contact has depth r − d and the
//    normal (centre − nearest)/d, and there is no contact when d ≥ r; a centre that crossed the wall into the
//    tissue is pushed back toward the lumen.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <span>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/core/units.hpp"
#include "support/airways.hpp"
#include "support/mesh_distance.hpp"

namespace magvine::anatomy {
namespace {

/// Winding number of the closed, outward-oriented mesh around p: 1 inside, 0 outside.
double winding_number(const TriangleMesh& mesh, const Vec3& p) {
  double total = 0.0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3 a = mesh.vertices[t[0]] - p;
    const Vec3 b = mesh.vertices[t[1]] - p;
    const Vec3 c = mesh.vertices[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    total += 2.0 * std::atan2(num, den);
  }
  return total / (4.0 * kPi);
}

/// Points near the wall on both sides: random surface points moved along the inward normal by −1 … 4 mm.
std::vector<Vec3> points_near_wall(const TriangleMesh& mesh, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, mesh.triangles.size() - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> offset(-1.0 * kMmToM, 4.0 * kMmToM);
  std::vector<Vec3> points;
  while (static_cast<int>(points.size()) < count) {
    const Triangle& t = mesh.triangles[pick(rng)];
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a);
    if (n.norm() == 0.0) continue;
    double u = unit(rng), v = unit(rng);
    if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
    points.push_back(a + u * (b - a) + v * (c - a) - offset(rng) * n.normalized());
  }
  return points;
}

class RealAirway : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    const auto file = ::test::airway_file(GetParam());
    if (!file) GTEST_SKIP() << GetParam() << " not found (../shared/airways absent)";
    mesh = import_mesh(*file, {.units = LengthUnit::kMm}).mesh;
  }
  TriangleMesh mesh;
};

/// Whether two contact lists are the same to the bit: a cached query tests the same triangles in the same order
/// with the same arithmetic as the uncached one, so anything else is a bug, not rounding.
bool identical(std::span<const Contact> a, std::span<const Contact> b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].point != b[i].point || a[i].normal != b[i].normal || a[i].depth != b[i].depth ||
        a[i].triangle != b[i].triangle) {
      return false;
    }
  }
  return true;
}

TEST_P(RealAirway, CachedSphereContactsEqualTheUncached) {
  const CollisionWorld world(mesh);
  const double r = 1.5 * kMmToM;
  const double margin = 0.3 * kMmToM;
  // Steps of a node between queries: none, within the margin, about the margin, beyond it (a refill).
  const std::array<double, 5> steps = {0.0, 0.05 * kMmToM, 0.2 * kMmToM, 0.299 * kMmToM, 0.45 * kMmToM};
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  ContactCache cache(margin);
  std::array<Contact, 8> plain;
  std::array<Contact, 8> cached;
  int mismatches = 0;
  int queries = 0;
  int with_contacts = 0;
  for (const Vec3& start : points_near_wall(mesh, 150, 22)) {
    Vec3 c = start;
    for (int q = 0; q < 12; ++q) {
      const Vec3 dir = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
      c += steps[static_cast<std::size_t>(q) % steps.size()] * dir;
      // Mostly the fill radius, sometimes smaller (kept), sometimes larger (a refill).
      const double radius = q % 4 == 3 ? 1.2 * kMmToM : q % 7 == 6 ? 1.8 * kMmToM : r;
      const std::size_t n = world.sphere_contacts(c, radius, plain);
      const std::size_t m = world.sphere_contacts(c, radius, cached, cache);
      mismatches += identical({plain.data(), n}, {cached.data(), m}) ? 0 : 1;
      ++queries;
      with_contacts += n > 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(mismatches, 0) << "of " << queries << " queries";
  EXPECT_GT(with_contacts, queries / 2);
  EXPECT_TRUE(cache.filled());
}

TEST_P(RealAirway, ContainsAgreesWithTheWindingNumber) {
  const CollisionWorld world(mesh);
  int inside = 0;
  for (const Vec3& p : points_near_wall(mesh, 120, 5)) {
    const double w = winding_number(mesh, p);
    // A closed oriented surface gives 0 or 1 up to round-off in the solid-angle sum; anything else means p lies
    // on the surface (not sampled here) or the mesh is not closed.
    ASSERT_NEAR(w, std::round(w), 1e-6) << "p = " << p.transpose();
    EXPECT_EQ(world.contains(p), std::round(w) == 1.0) << "p = " << p.transpose() << " winding " << w;
    inside += std::round(w) == 1.0 ? 1 : 0;
  }
  EXPECT_GT(inside, 60);  // the sample reaches both sides
  EXPECT_LT(inside, 120);
}

TEST_P(RealAirway, DeepestSphereContactIsTheWallDistance) {
  const CollisionWorld world(mesh);
  const magvine::test::BruteForceDistance distance(mesh);
  const double r = 1.5 * kMmToM;
  // Depth and distance come from different formulas on the same coordinates (plane distance of the foot vs
  // closest point on the triangle): round-off ~1e-16 m each; 1e-12 m is still 1e6 below the wall's triangle size.
  constexpr double kDepthTol = 1e-12;
  constexpr double kNormalTol = 1e-9;  // a direction divided by a distance ≥ 1 µm: ≤ 1e-12 / 1e-6
  std::array<Contact, 32> out;
  int touching = 0;
  int checked = 0;
  for (const Vec3& p : points_near_wall(mesh, 4000, 9)) {
    if (!world.contains(p)) continue;
    ++checked;
    const magvine::test::MeshNearest d = distance.point(p);
    const std::size_t n = world.sphere_contacts(p, r, out);
    if (d.distance >= r) {
      EXPECT_EQ(n, 0u) << "p = " << p.transpose() << " wall at " << d.distance;
      continue;
    }
    ++touching;
    ASSERT_GE(n, 1u) << "p = " << p.transpose() << " wall at " << d.distance;
    EXPECT_NEAR(out[0].depth, r - d.distance, kDepthTol) << "p = " << p.transpose();
    if (d.distance > 1e-6) {
      const Vec3 expected = (p - d.on_mesh) / d.distance;
      EXPECT_LT((out[0].normal - expected).norm(), kNormalTol) << "p = " << p.transpose();
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_GT(touching, 500);
}

TEST_P(RealAirway, DeepestCapsuleContactIsTheAxisDistance) {
  // Capsules 2 mm long, random directions, axis wholly in the lumen (both ends inside, axis distance s > 0, so it
  // crosses no wall): deepest depth r − s and normal (on_segment − on_mesh)/s, no contact when s ≥ r.
  const CollisionWorld world(mesh);
  const magvine::test::BruteForceDistance distance(mesh);
  const double r = 1.5 * kMmToM;
  const double half = 1.0 * kMmToM;
  constexpr double kDepthTol = 1e-12;  // round-off on millimetre coordinates, as for spheres
  constexpr double kNormalTol = 1e-9;
  std::mt19937 rng(21);
  std::normal_distribution<double> gauss;
  std::array<Contact, 32> out;
  int touching = 0;
  int checked = 0;
  for (const Vec3& c : points_near_wall(mesh, 3000, 17)) {
    const Vec3 axis = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const Vec3 a = c - half * axis;
    const Vec3 b = c + half * axis;
    if (!world.contains(a) || !world.contains(b)) continue;
    const magvine::test::MeshNearest d = distance.segment(a, b);
    if (d.distance < 1e-6) continue;  // touches or crosses a wall
    ++checked;
    const std::size_t n = world.capsule_contacts(a, b, r, out);
    if (d.distance >= r) {
      EXPECT_EQ(n, 0u) << "a = " << a.transpose() << " b = " << b.transpose();
      continue;
    }
    ++touching;
    ASSERT_GE(n, 1u) << "a = " << a.transpose() << " b = " << b.transpose();
    EXPECT_NEAR(out[0].depth, r - d.distance, kDepthTol) << "a = " << a.transpose() << " b = " << b.transpose();
    const Vec3 expected = (d.on_query - d.on_mesh) / d.distance;
    EXPECT_LT((out[0].normal - expected).norm(), kNormalTol) << "a = " << a.transpose() << " b = " << b.transpose();
  }
  EXPECT_GT(checked, 500);
  EXPECT_GT(touching, 300);
}

TEST_P(RealAirway, SphereWhoseCentreCrossedTheWallIsPushedBack) {
  // Centres up to r/2 into the tissue (contains() false, wall distance d < r/2) must never go unnoticed: at
  // least one contact, the deepest deeper than the radius (the centre is behind that face). Which way to push
  // is decided per face, so where tissue thinner than the sphere separates two lumens (septa between branches,
  // folds of the voxel staircase) a penalty force Σ depth·normal can point at the other lumen; on smooth walls it
  // points at the nearest wall point. Measured share of such cases below; bounded loosely so a regression that
  // flips pushes wholesale fails.
  const CollisionWorld world(mesh);
  const magvine::test::BruteForceDistance distance(mesh);
  const double r = 1.5 * kMmToM;
  std::array<Contact, 32> out;
  int checked = 0;
  int toward_nearest = 0;
  for (const Vec3& p : points_near_wall(mesh, 3000, 13)) {
    if (world.contains(p)) continue;
    const magvine::test::MeshNearest d = distance.point(p);
    if (d.distance >= 0.5 * r || d.distance < 1e-6) continue;
    ++checked;
    const std::size_t n = world.sphere_contacts(p, r, out);
    ASSERT_GE(n, 1u) << "p = " << p.transpose();
    EXPECT_GT(out[0].depth, r) << "p = " << p.transpose();
    Vec3 force = Vec3::Zero();
    for (std::size_t i = 0; i < n; ++i) force += out[i].depth * out[i].normal;
    toward_nearest += force.dot(d.on_mesh - p) > 0.0 ? 1 : 0;
  }
  ASSERT_GT(checked, 200);
  const double share = static_cast<double>(toward_nearest) / checked;
  std::printf("%s: %d centres in the tissue, penalty force toward the nearest wall point for %.1f %%\n", GetParam(),
              checked, 100.0 * share);
  EXPECT_GT(share, 0.95);  // measured: siliconmodel3 100 %, lidc0525 97.5 %
}

INSTANTIATE_TEST_SUITE_P(Meshes, RealAirway,
                         ::testing::Values("siliconmodel3_airway.stl", "lidc0525_medmpd_p5_airway_mc.stl"),
                         [](const auto& param_info) { return std::string(param_info.param).substr(0, 8); });

}  // namespace
}  // namespace magvine::anatomy
