// The collision world's BVH (private header src/anatomy/src/triangle_bvh.hpp): its leaves hold every triangle
// exactly once, and its sphere, box and ray walks visit every triangle a brute-force loop over the exact (double)
// triangle boxes says they must. Missing one would silently lose contacts, so the reference is exhaustive.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "support/airways.hpp"
#include "triangle_bvh.hpp"

namespace magvine::anatomy::detail {
namespace {

struct Box {
  Vec3 lo;
  Vec3 hi;
};

Box triangle_box(const TriangleMesh& mesh, std::size_t t) {
  const Triangle& tri = mesh.triangles[t];
  const Vec3& a = mesh.vertices[tri[0]];
  const Vec3& b = mesh.vertices[tri[1]];
  const Vec3& c = mesh.vertices[tri[2]];
  return {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c)};
}

/// Triangles visited by a walk, as a flag per triangle; fails the test if one is visited twice.
template <class Test>
std::vector<char> visited(const TriangleBvh& bvh, std::size_t triangles, Test&& test) {
  std::vector<char> seen(triangles, 0);
  bvh.visit_slots(test, [&](std::uint32_t slot) {
    const std::uint32_t t = bvh.order()[slot];
    EXPECT_EQ(seen[t], 0) << "triangle " << t << " visited twice";
    seen[t] = 1;
  });
  return seen;
}

/// Checks the BVH of `mesh` against brute force for random spheres, boxes and rays around the mesh.
void check_walks(const TriangleMesh& mesh, double radius, int queries) {
  const TriangleBvh bvh(mesh.vertices, mesh.triangles);
  const std::size_t n = mesh.triangles.size();

  // The leaves are a permutation of the triangles.
  std::vector<std::uint32_t> sorted(bvh.order().begin(), bvh.order().end());
  std::sort(sorted.begin(), sorted.end());
  ASSERT_EQ(sorted.size(), n);
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(sorted[i], i);

  const Aabb all = bounding_box(mesh);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto point = [&] {
    const Vec3 f(u(rng), u(rng), u(rng));
    return Vec3(all.min + f.cwiseProduct(all.max - all.min));
  };
  std::size_t sphere_hits = 0;
  std::size_t sphere_visits = 0;
  for (int q = 0; q < queries; ++q) {
    // Centres on the surface (a random triangle's centroid, shifted) so that most queries touch something.
    const Triangle& tri = mesh.triangles[rng() % n];
    const Vec3 c = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0 +
                   radius * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    const auto spheres =
        visited(bvh, n, [&](const TriangleBvh::Node& node) { return sphere_mask(node, c, radius * radius); });
    const Vec3 lo = c - Vec3::Constant(radius);
    const Vec3 hi = c + Vec3(0.5 * radius, 2.0 * radius, radius);
    const auto boxes = visited(bvh, n, [&](const TriangleBvh::Node& node) { return box_mask(node, lo, hi); });
    const Vec3 origin = point();
    const Vec3 dir = (c - origin).normalized();
    const double length = (c - origin).norm();
    const Vec3 inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());
    const auto rays =
        visited(bvh, n, [&](const TriangleBvh::Node& node) { return ray_mask(node, origin, inv, length); });
    for (std::size_t t = 0; t < n; ++t) {
      const Box b = triangle_box(mesh, t);
      // Sphere: squared distance from c to the exact box.
      const double d2 = (c.cwiseMax(b.lo).cwiseMin(b.hi) - c).squaredNorm();
      if (d2 <= radius * radius) {
        ++sphere_hits;
        EXPECT_TRUE(spheres[t]) << "sphere walk missed triangle " << t;
      }
      sphere_visits += static_cast<std::size_t>(spheres[t]);
      const bool overlap = (b.lo.array() <= hi.array()).all() && (b.hi.array() >= lo.array()).all();
      if (overlap) {
        EXPECT_TRUE(boxes[t]) << "box walk missed triangle " << t;
      }
      // Ray: exact slab test of the segment against the box.
      double t0 = 0.0;
      double t1 = length;
      for (int a = 0; a < 3; ++a) {
        const double near = ((dir[a] >= 0.0 ? b.lo[a] : b.hi[a]) - origin[a]) * inv[a];
        const double far = ((dir[a] >= 0.0 ? b.hi[a] : b.lo[a]) - origin[a]) * inv[a];
        t0 = std::max(t0, near);
        t1 = std::min(t1, far);
      }
      if (t0 <= t1) {
        EXPECT_TRUE(rays[t]) << "ray walk missed triangle " << t;
      }
    }
  }
  EXPECT_GT(sphere_hits, static_cast<std::size_t>(queries));  // the queries did touch the surface
  // Selectivity, loosely: the walk reads leaves, so it visits more than the exact set, but not the whole mesh.
  EXPECT_LT(sphere_visits, 4 * sphere_hits + 8 * static_cast<std::size_t>(queries));
}

TEST(TriangleBvh, WalksVisitEveryTriangleTheBruteForceBoxesReach) {
  check_walks(make_tube({.radius = 5e-3, .length = 40e-3, .segments = 48, .rings = 60, .capped = true}), 1.5e-3, 60);
}

/// The leaves a walk reaches, in order, as (first slot, count).
template <class Test>
std::vector<std::pair<std::uint32_t, std::uint32_t>> leaves(const TriangleBvh& bvh, Test&& test) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  bvh.walk(test, [&](std::uint32_t first, std::uint32_t count) { out.emplace_back(first, count); });
  return out;
}

/// The single-precision node tests (SphereBoxTest, BoxBoxTest) reach exactly the leaves of the double ones
/// (sphere_mask, box_mask), in the same order: random queries, and queries whose radius or box face sits exactly
/// on a leaf's box (and one float step either side), where only the exact fallback can decide.
void check_float_tests(const TriangleMesh& mesh, double radius, int queries) {
  const TriangleBvh bvh(mesh.vertices, mesh.triangles);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto nodes = bvh.nodes();
  std::size_t reached = 0;
  for (int q = 0; q < queries; ++q) {
    const Triangle& tri = mesh.triangles[rng() % mesh.triangles.size()];
    const Vec3 c = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0 +
                   radius * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    // A leaf child of a random node: the exact distance to its box (sphere_mask's arithmetic) as a radius.
    const TriangleBvh::Node& node = nodes[rng() % nodes.size()];
    const std::size_t k = rng() % 4;
    const double dx = std::max({0.0, node.lo_x[k] - c.x(), c.x() - node.hi_x[k]});
    const double dy = std::max({0.0, node.lo_y[k] - c.y(), c.y() - node.hi_y[k]});
    const double dz = std::max({0.0, node.lo_z[k] - c.z(), c.z() - node.hi_z[k]});
    const double edge = std::sqrt(dx * dx + dy * dy + dz * dz);
    for (const double r :
         {radius * (0.2 + u(rng)), edge, std::nextafter(edge, 0.0), std::nextafter(edge, 1.0), 1e-12}) {
      if (!(r > 0.0)) continue;
      const auto exact = leaves(bvh, [&](const TriangleBvh::Node& n) { return sphere_mask(n, c, r * r); });
      EXPECT_EQ(leaves(bvh, SphereBoxTest(c, r)), exact) << "sphere at query " << q << ", r = " << r;
      reached += exact.size();
    }
    // Boxes: a random one, and ones whose upper x face is exactly a leaf box's lower x face or one double below
    // it (which rounds up onto it in float).
    const Vec3 lo = c - radius * Vec3(u(rng), u(rng), u(rng));
    const double face = node.lo_x[k];
    const std::array<Vec3, 3> highs = {Vec3(c + radius * Vec3(u(rng), u(rng), u(rng))),
                                       Vec3(face, c.y() + radius, c.z() + radius),
                                       Vec3(std::nextafter(face, -1.0), c.y() + radius, c.z() + radius)};
    for (const Vec3& hi : highs) {
      const auto exact = leaves(bvh, [&](const TriangleBvh::Node& n) { return box_mask(n, lo, hi); });
      EXPECT_EQ(leaves(bvh, BoxBoxTest(lo, hi)), exact) << "box at query " << q;
    }
  }
  EXPECT_GT(reached, static_cast<std::size_t>(queries));
}

TEST(TriangleBvh, FloatNodeTestsReachTheExactLeaves) {
  check_float_tests(make_tube({.radius = 5e-3, .length = 40e-3, .segments = 48, .rings = 60, .capped = true}), 1.5e-3,
                    400);
}

TEST(TriangleBvh, SingleTriangleMeshHasARootLeaf) {
  TriangleMesh mesh;
  mesh.vertices = {Vec3(0, 0, 0), Vec3(1e-3, 0, 0), Vec3(0, 1e-3, 0)};
  mesh.triangles = {{0, 1, 2}};
  const TriangleBvh bvh(mesh.vertices, mesh.triangles);
  ASSERT_EQ(bvh.order().size(), 1u);
  const auto near =
      visited(bvh, 1, [](const TriangleBvh::Node& n) { return sphere_mask(n, Vec3(0, 0, 1e-4), 2e-4 * 2e-4); });
  EXPECT_TRUE(near[0]);
  const auto far =
      visited(bvh, 1, [](const TriangleBvh::Node& n) { return sphere_mask(n, Vec3(0, 0, 1e-3), 2e-4 * 2e-4); });
  EXPECT_FALSE(far[0]);
}

/// A refit's boxes (TriangleBvh::refit: the outward rounding folded into the pad) hold every triangle of their
/// subtree, compared in double, for a tube moved far from the origin where a float's ulp (7.6e-6 at 100) is a
/// sizeable part of its 0.65 mm triangles, and are no looser than the pad and two ulps allow.
TEST(TriangleBvh, RefitBoxesHoldTheirTrianglesFarFromTheOrigin) {
  TriangleMesh mesh = make_tube({.radius = 5e-3, .length = 40e-3, .segments = 48, .rings = 60, .capped = true});
  TriangleBvh bvh(mesh.vertices, mesh.triangles);
  std::vector<std::array<std::uint32_t, 3>> corners(bvh.order().size());
  for (std::size_t slot = 0; slot < corners.size(); ++slot) {
    const Triangle& t = mesh.triangles[bvh.order()[slot]];
    corners[slot] = {t[0], t[1], t[2]};
  }
  bvh.prepare_refit(corners);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1e-4, 1e-4);
  for (const Vec3& offset : {Vec3(0.0, 0.0, 0.0), Vec3(123.4, -57.1, 0.3), Vec3(-0.25, 1e-3, 96.0)}) {
    std::vector<Vec3> moved = mesh.vertices;
    for (Vec3& v : moved) v += offset + Vec3(u(rng), u(rng), u(rng));
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
    Vec3 hi = -lo;
    for (const Vec3& v : moved) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    bvh.refit(moved, lo, hi);
    const double ulp = std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()) * 0x1p-23;
    const double slack = 1e-7 * (hi - lo).norm() + 4.0 * ulp;  // the pad, the folded rounding, the float's own
    const auto nodes = bvh.nodes();
    // Every child box, leaf or inner, against the exact box of the triangles beneath it.
    std::vector<std::pair<Vec3, Vec3>> exact(nodes.size());
    for (std::size_t i = nodes.size(); i-- > 0;) {
      Vec3 node_lo = Vec3::Constant(std::numeric_limits<double>::infinity());
      Vec3 node_hi = -node_lo;
      for (std::size_t k = 0; k < 4; ++k) {
        const std::uint32_t c = nodes[i].child[k];
        Vec3 a = Vec3::Constant(std::numeric_limits<double>::infinity());
        Vec3 b = -a;
        if ((c & TriangleBvh::kLeafBit) != 0) {
          const std::uint32_t first = (c & ~TriangleBvh::kLeafBit) >> 4;
          for (std::uint32_t slot = first; slot < first + (c & 0xFu); ++slot) {
            for (const std::uint32_t v : corners[slot]) {
              a = a.cwiseMin(moved[v]);
              b = b.cwiseMax(moved[v]);
            }
          }
        } else {
          std::tie(a, b) = exact[c];
        }
        if (!(a.array() <= b.array()).all()) continue;  // an empty child
        const Vec3 box_lo(nodes[i].lo_x[k], nodes[i].lo_y[k], nodes[i].lo_z[k]);
        const Vec3 box_hi(nodes[i].hi_x[k], nodes[i].hi_y[k], nodes[i].hi_z[k]);
        EXPECT_TRUE((box_lo.array() <= a.array()).all() && (box_hi.array() >= b.array()).all())
            << "node " << i << " child " << k << " at offset " << offset.transpose();
        EXPECT_LE((a - box_lo).maxCoeff(), slack);
        EXPECT_LE((box_hi - b).maxCoeff(), slack);
        node_lo = node_lo.cwiseMin(a);
        node_hi = node_hi.cwiseMax(b);
      }
      exact[i] = {node_lo, node_hi};
    }
  }
}

TEST(TriangleBvh, RealAirwayWalksAreComplete) {
  const auto path = test::airway_file("siliconmodel3_airway.stl");
  if (!path) GTEST_SKIP() << "../shared/airways absent";
  check_walks(import_mesh(*path).mesh, 1.5e-3, 20);
  check_float_tests(import_mesh(*path).mesh, 1.5e-3, 200);
}

}  // namespace
}  // namespace magvine::anatomy::detail
