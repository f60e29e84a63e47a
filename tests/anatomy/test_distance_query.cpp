// DistanceQuery: analytic distances in a tessellated tube, brute force over all triangles on a perturbed tube,
// the capsule cases (clear, overlapping, axis crossing the wall), bad input, warm start and threads.

#include "magvine/anatomy/distance_query.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "support/compare.hpp"

namespace magvine::anatomy {
namespace {

using magvine::test::close;

// Round-off budget. Coordinates are ≤ 0.1 m (≤ 1 m for the far points) and doubles carry 2.2e-16 relative; the
// closest-point formulas lose a few digits to cancellation at most (errors seen: ≤ 3e-17 m). 1e-12 of the scene
// size leaves a wide margin and is still far below what the errors it guards against cost (a wrong Voronoi region,
// an invalid pruning bound, a missed crossing: µm to mm here).
constexpr double kRelTol = 1e-12;

// The tube every analytic test uses: R = 5 mm, 64 segments, capped, 0.1 m long (~square triangles).
constexpr double kR = 5e-3;
constexpr int kSegments = 64;
constexpr double kLength = 0.1;
const double kApothem = kR * std::cos(kPi / kSegments);  // distance from the axis to a wall facet
constexpr double kTubeTol = kRelTol * kLength;            // absolute round-off budget in the tube [m]

TriangleMesh tube() { return make_tube({.radius = kR, .length = kLength, .segments = kSegments, .rings = 0, .capped = true}); }

/// Unit vector at angle phi in the xy-plane.
Vec3 radial(double phi) { return {std::cos(phi), std::sin(phi), 0.0}; }
/// Angle of vertex i (make_tube puts vertex i of every ring at 2πi/n) and of the middle of wall facet i.
double vertex_angle(int i) { return 2.0 * kPi * i / kSegments; }
double facet_angle(int i) { return 2.0 * kPi * (i + 0.5) / kSegments; }

// ---- Reference implementations written independently of the library ----------------------------------------

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection §5.1.5), written here again in the
/// barycentric form of the book; a degenerate triangle is not handled (the reference meshes have none).
Vec3 reference_closest(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  const double d1 = ab.dot(p - a), d2 = ac.dot(p - a);
  if (d1 <= 0 && d2 <= 0) return a;
  const double d3 = ab.dot(p - b), d4 = ac.dot(p - b);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const double d5 = ab.dot(p - c), d6 = ac.dot(p - c);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double reference_triangle_distance(const TriangleMesh& mesh, std::size_t t, const Vec3& p) {
  return (reference_closest(p, corner(mesh, t, 0), corner(mesh, t, 1), corner(mesh, t, 2)) - p).norm();
}

/// Brute force: the distance to every triangle.
double brute_force_distance(const TriangleMesh& mesh, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) best = std::min(best, reference_triangle_distance(mesh, t, p));
  return best;
}

/// Brute force segment distance by a different method than the library's: per triangle, t ↦ dist(a + t(b−a),
/// triangle) is convex (distance to a convex set along a line), so ternary search finds its minimum; 150 steps
/// shrink the bracket by (2/3)^150 ≈ 4e-27, i.e. below round-off.
double brute_force_segment_distance(const TriangleMesh& mesh, const Vec3& a, const Vec3& b) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto f = [&](double s) { return reference_triangle_distance(mesh, t, a + s * (b - a)); };
    double lo = 0.0, hi = 1.0;
    for (int k = 0; k < 150; ++k) {
      const double m1 = lo + (hi - lo) / 3.0, m2 = hi - (hi - lo) / 3.0;
      if (f(m1) <= f(m2)) hi = m2; else lo = m1;
    }
    best = std::min({best, f(0.5 * (lo + hi)), f(0.0), f(1.0)});
  }
  return best;
}

/// A tube of 200 triangles (20 segments × 4 bands + 2 caps of 20) with every vertex moved by up to ±0.3 mm: no
/// symmetry left, so ties and lucky alignments cannot hide a traversal error.
TriangleMesh perturbed_tube() {
  TriangleMesh mesh = make_tube({.radius = 5e-3, .length = 0.02, .segments = 20, .rings = 5, .capped = true});
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> jitter(-0.3e-3, 0.3e-3);
  for (Vec3& v : mesh.vertices) v += Vec3(jitter(rng), jitter(rng), jitter(rng));
  return mesh;
}

/// Size of a mesh for relative tolerances: its bounding-box diagonal [m].
double mesh_size(const TriangleMesh& mesh) {
  const Aabb box = bounding_box(mesh);
  return (box.max - box.min).norm();
}

/// Query points around a mesh: uniform in the box grown by 5 mm, near the surface (±0.5 mm off a random point of a
/// random triangle, never exactly on it), and 1 m away.
std::vector<Vec3> points_around(const TriangleMesh& mesh, int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Aabb box = bounding_box(mesh);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_int_distribution<std::size_t> pick(0, mesh.triangles.size() - 1);
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) {
    if (i % 25 == 24) {
      points.push_back(Vec3(u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5).normalized() * 1.0);
    } else if (i % 3 == 0) {
      const Vec3 lo = box.min - Vec3::Constant(5e-3), hi = box.max + Vec3::Constant(5e-3);
      points.push_back(lo + Vec3(u01(rng), u01(rng), u01(rng)).cwiseProduct(hi - lo));
    } else {
      const std::size_t t = pick(rng);
      double s = u01(rng), w = u01(rng);
      if (s + w > 1.0) { s = 1.0 - s; w = 1.0 - w; }
      const Vec3 on = corner(mesh, t, 0) + s * (corner(mesh, t, 1) - corner(mesh, t, 0)) +
                      w * (corner(mesh, t, 2) - corner(mesh, t, 0));
      const double offset = (u01(rng) < 0.5 ? -1.0 : 1.0) * (1e-6 + 0.5e-3 * u01(rng));
      points.push_back(on + offset * area_vector(mesh, t).normalized());
    }
  }
  return points;
}

/// Segments 1–13 mm long in random directions from points_around() (far points left out): many cross the wall.
std::vector<std::pair<Vec3, Vec3>> sample_segments(const TriangleMesh& mesh) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  std::vector<std::pair<Vec3, Vec3>> segments;
  const std::vector<Vec3> starts = points_around(mesh, 120, 21);
  for (std::size_t i = 0; i < starts.size(); ++i) {
    if (starts[i].norm() > 0.5) continue;
    const Vec3 dir = Vec3(n01(rng), n01(rng), n01(rng)).normalized();
    segments.emplace_back(starts[i], starts[i] + (1e-3 + 4e-3 * static_cast<double>(i % 4)) * dir);
  }
  return segments;
}

// ---- Tube: analytic distances ------------------------------------------------------------------------------

TEST(TubeDistance, OnAxisPointIsTheApothem) {
  // From the axis the nearest wall points are the facet centres at distance R·cos(π/n), not the vertices at R.
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  for (const double z : {0.02, 0.05, 0.0503, 0.08}) {
    const Vec3 p(0.0, 0.0, z);
    const PointDistance d = query.nearest_point(p, ws);
    EXPECT_NEAR(d.distance, kApothem, kTubeTol) << "z = " << z;
    EXPECT_GT(kR - d.distance, 1e-6) << "a vertex distance R was reported instead of the apothem";
    EXPECT_NEAR((d.nearest - p).norm(), d.distance, kTubeTol);
    EXPECT_NEAR(d.nearest.z(), z, kTubeTol);
    // The foot lies at the middle of a facet: its angle is (i + ½)·2π/n for some i.
    const double steps = std::atan2(d.nearest.y(), d.nearest.x()) / (2.0 * kPi / kSegments) - 0.5;
    EXPECT_NEAR(steps, std::round(steps), 1e-9);
    ASSERT_GE(d.triangle, 0);
    ASSERT_LT(d.triangle, static_cast<std::int64_t>(query.num_triangles()));
  }
}

TEST(TubeDistance, OffAxisPointsTowardFacetAndVertex) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  for (const double rho : {1e-3, 2.5e-3, 4.5e-3}) {
    // Toward the middle of facet 7: the facet plane is kApothem from the axis.
    const Vec3 p_facet = rho * radial(facet_angle(7)) + Vec3(0, 0, 0.04);
    const PointDistance d_facet = query.nearest_point(p_facet, ws);
    EXPECT_NEAR(d_facet.distance, kApothem - rho, kTubeTol) << "rho = " << rho;
    EXPECT_TRUE(close(d_facet.nearest, Vec3(kApothem * radial(facet_angle(7)) + Vec3(0, 0, 0.04)), 0.0, kTubeTol));
    // Toward vertex 3: both neighbouring facet planes are (R − ρ)·cos(π/n) away, the vertex ridge R − ρ.
    const Vec3 p_vertex = rho * radial(vertex_angle(3)) + Vec3(0, 0, 0.06);
    EXPECT_NEAR(query.nearest_point(p_vertex, ws).distance, (kR - rho) * std::cos(kPi / kSegments), kTubeTol)
        << "rho = " << rho;
  }
}

TEST(TubeDistance, PointNearCapHitsTheCap) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  // 0.4 mm above the bottom cap, 1 mm off the axis: the cap (0.4 mm) is nearer than the wall (~4 mm).
  const Vec3 bottom = 1e-3 * radial(0.3) + Vec3(0, 0, 0.4e-3);
  const PointDistance d = query.nearest_point(bottom, ws);
  EXPECT_NEAR(d.distance, 0.4e-3, kTubeTol);
  EXPECT_TRUE(close(d.nearest, Vec3(bottom.x(), bottom.y(), 0.0), 0.0, kTubeTol));
  const Vec3 top = 2e-3 * radial(2.0) + Vec3(0, 0, kLength - 0.7e-3);
  EXPECT_NEAR(query.nearest_point(top, ws).distance, 0.7e-3, kTubeTol);
  // Near the rim the cap and the wall compete: 0.2 mm below the top, 0.3 mm inside facet 5's plane → 0.2 mm.
  const Vec3 rim = (kApothem - 0.3e-3) * radial(facet_angle(5)) + Vec3(0, 0, kLength - 0.2e-3);
  EXPECT_NEAR(query.nearest_point(rim, ws).distance, 0.2e-3, kTubeTol);
}

TEST(TubeDistance, PointsOutsideAndFar) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  for (const double h : {1e-4, 2e-3}) {
    // Radially outside a vertex: the nearest point is on the vertex ridge (an edge along z), h away.
    const Vec3 p_vertex = (kR + h) * radial(vertex_angle(10)) + Vec3(0, 0, 0.03);
    const PointDistance d = query.nearest_point(p_vertex, ws);
    EXPECT_NEAR(d.distance, h, kTubeTol);
    EXPECT_TRUE(close(d.nearest, Vec3(kR * radial(vertex_angle(10)) + Vec3(0, 0, 0.03)), 0.0, kTubeTol));
    // Radially outside a facet middle: h from the facet.
    const Vec3 p_facet = (kApothem + h) * radial(facet_angle(40)) + Vec3(0, 0, 0.07);
    EXPECT_NEAR(query.nearest_point(p_facet, ws).distance, h, kTubeTol);
  }
  // 1 m away: below the bottom cap centre, and beside vertex 0.
  constexpr double kFarTol = kRelTol * 1.0;  // scene size 1 m
  const PointDistance below = query.nearest_point(Vec3(0, 0, -1.0), ws);
  EXPECT_NEAR(below.distance, 1.0, kFarTol);
  EXPECT_TRUE(close(below.nearest, Vec3(0, 0, 0), 0.0, kFarTol));
  EXPECT_NEAR(query.nearest_point(Vec3(1.0, 0, kLength / 2), ws).distance, 1.0 - kR, kFarTol);
}

TEST(TubeDistance, NearestPointLiesOnTheReportedTriangle) {
  const TriangleMesh mesh = tube();
  const DistanceQuery query(mesh);
  DistanceWorkspace ws = query.make_workspace();
  for (const Vec3& p : points_around(mesh, 300, 7)) {
    const PointDistance d = query.nearest_point(p, ws);
    ASSERT_GE(d.triangle, 0);
    const double scale = std::max(kLength, p.norm());
    EXPECT_NEAR((d.nearest - p).norm(), d.distance, kRelTol * scale);
    EXPECT_NEAR(reference_triangle_distance(mesh, static_cast<std::size_t>(d.triangle), d.nearest), 0.0,
                kRelTol * scale);
  }
}

TEST(LumenRadius, IsTheWallDistance) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  EXPECT_NEAR(query.lumen_radius(Vec3(0, 0, 0.05), ws), kApothem, kTubeTol);
  const Vec3 off = 3e-3 * radial(1.0) + Vec3(0, 0, 0.02);
  const double r = query.lumen_radius(off, ws);
  EXPECT_LT(r, kApothem - 2e-3);  // off-centre: the clearance, smaller than the lumen's radius
  EXPECT_NEAR(r, query.nearest_point(off, ws).distance, 0.0);
}

// ---- Capsules ------------------------------------------------------------------------------------------------

TEST(CapsuleDistance, InsideTubeIsWallDistanceMinusRadius) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  constexpr double r = 2e-3;
  // On the axis, z from 30 to 70 mm: every point of the axis is kApothem from the wall.
  const CapsuleDistance axial = query.capsule_distance(Vec3(0, 0, 0.03), Vec3(0, 0, 0.07), r, ws);
  EXPECT_NEAR(axial.distance, kApothem - r, kTubeTol);
  EXPECT_NEAR(axial.axis_distance, kApothem, kTubeTol);
  EXPECT_FALSE(axial.intersects);
  EXPECT_FALSE(axial.axis_crosses_wall);
  EXPECT_NEAR(axial.on_capsule.head<2>().norm(), r, kTubeTol);
  EXPECT_NEAR((axial.on_mesh - axial.on_capsule).norm(), axial.distance, kTubeTol);
  EXPECT_NEAR(axial.on_segment.head<2>().norm(), 0.0, kTubeTol);
  // Parallel to the axis, 1.5 mm toward facet 20.
  const Vec3 off = 1.5e-3 * radial(facet_angle(20));
  const CapsuleDistance parallel = query.capsule_distance(off + Vec3(0, 0, 0.01), off + Vec3(0, 0, 0.09), r, ws);
  EXPECT_NEAR(parallel.distance, kApothem - 1.5e-3 - r, kTubeTol);
  EXPECT_TRUE(close(parallel.on_mesh.head<2>(), Vec3(kApothem * radial(facet_angle(20))).head<2>(), 0.0, kTubeTol));
  // Across the lumen through the axis toward vertices 0 and 32, ±3 mm: the endpoints are nearest, each
  // (R − 3 mm)·cos(π/n) from the two facets beside its vertex.
  const CapsuleDistance across =
      query.capsule_distance(Vec3(-3e-3, 0, 0.05), Vec3(3e-3, 0, 0.05), 0.5e-3, ws);
  EXPECT_NEAR(across.axis_distance, (kR - 3e-3) * std::cos(kPi / kSegments), kTubeTol);
  EXPECT_NEAR(across.distance, (kR - 3e-3) * std::cos(kPi / kSegments) - 0.5e-3, kTubeTol);
  EXPECT_NEAR(std::abs(across.on_segment.x()), 3e-3, kTubeTol);
}

TEST(CapsuleDistance, OverlappingTheWallGivesNegativeClearance) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  // Axis 3 mm toward facet 9, radius 2.5 mm: the capsule sinks 2.5 − (kApothem − 3) ≈ 0.5 mm into the wall.
  const Vec3 off = 3e-3 * radial(facet_angle(9));
  constexpr double r = 2.5e-3;
  const CapsuleDistance c = query.capsule_distance(off + Vec3(0, 0, 0.04), off + Vec3(0, 0, 0.05), r, ws);
  EXPECT_TRUE(c.intersects);
  EXPECT_FALSE(c.axis_crosses_wall);
  EXPECT_NEAR(c.axis_distance, kApothem - 3e-3, kTubeTol);
  EXPECT_NEAR(c.distance, kApothem - 3e-3 - r, kTubeTol);
  EXPECT_LT(c.distance, -0.4e-3);
  // The deepest capsule point is beyond the wall by the overlap depth.
  EXPECT_NEAR((c.on_capsule - c.on_segment).norm(), r, kTubeTol);
  EXPECT_NEAR(c.on_capsule.head<2>().norm() - kApothem, -c.distance, kTubeTol);
}

TEST(CapsuleDistance, AxisCrossingTheWall) {
  const DistanceQuery query(tube());
  DistanceWorkspace ws = query.make_workspace();
  // From the axis out through the middle of facet 12 to 2R: the segment pierces the facet at radius kApothem.
  const Vec3 dir = radial(facet_angle(12));
  const Vec3 z(0, 0, 0.0451);
  constexpr double r = 1e-3;
  const CapsuleDistance c = query.capsule_distance(z, z + 2.0 * kR * dir, r, ws);
  EXPECT_TRUE(c.axis_crosses_wall);
  EXPECT_TRUE(c.intersects);
  EXPECT_NEAR(c.distance, -r, kTubeTol);
  EXPECT_TRUE(close(c.on_mesh, Vec3(z + kApothem * dir), 0.0, kTubeTol));
  EXPECT_TRUE(close(c.on_segment, c.on_mesh, 0.0, kTubeTol));
  EXPECT_TRUE(close(c.on_capsule, c.on_segment, 0.0, 0.0));
  // Entirely outside, 1 mm beyond a facet, parallel to the axis: no crossing, clearance 1 mm − r.
  const Vec3 out = (kApothem + 1e-3) * dir;
  const CapsuleDistance outside = query.capsule_distance(out + Vec3(0, 0, 0.02), out + Vec3(0, 0, 0.03), 0.4e-3, ws);
  EXPECT_FALSE(outside.intersects);
  EXPECT_NEAR(outside.distance, 0.6e-3, kTubeTol);
}

TEST(CapsuleDistance, DegenerateCapsules) {
  const TriangleMesh mesh = perturbed_tube();
  const DistanceQuery query(mesh);
  DistanceWorkspace ws = query.make_workspace();
  const double tol = kRelTol * mesh_size(mesh);
  for (const Vec3& p : points_around(mesh, 60, 11)) {
    // a = b: a sphere, its clearance is the point distance minus the radius.
    const double d = query.nearest_point(p, ws).distance;
    const CapsuleDistance sphere = query.capsule_distance(p, p, 1e-3, ws);
    EXPECT_NEAR(sphere.axis_distance, d, tol);
    EXPECT_NEAR(sphere.distance, d - 1e-3, tol);
    EXPECT_TRUE(close(sphere.on_segment, p, 0.0, 0.0));
    // radius 0: a segment, clearance = axis distance.
    const CapsuleDistance segment = query.capsule_distance(p, p + Vec3(1e-3, -2e-3, 0.5e-3), 0.0, ws);
    EXPECT_NEAR(segment.distance, segment.axis_distance, 0.0);
    EXPECT_LE(segment.axis_distance, d + tol);  // the segment starts at p
  }
}

// ---- Brute force over all triangles --------------------------------------------------------------------------

struct Variant {
  const char* name;
  DistanceQueryOptions options;
  bool warm_start;
};

std::ostream& operator<<(std::ostream& os, const Variant& v) { return os << v.name; }

class BruteForcePoints : public ::testing::TestWithParam<Variant> {};
class BruteForceSegments : public ::testing::TestWithParam<Variant> {};

TEST_P(BruteForcePoints, AgreeWithEveryTriangleChecked) {
  const TriangleMesh mesh = perturbed_tube();
  ASSERT_EQ(mesh.triangles.size(), 200u);
  const DistanceQuery query(mesh, GetParam().options);
  DistanceWorkspace ws = query.make_workspace();
  ws.warm_start = GetParam().warm_start;
  const double size = mesh_size(mesh);
  for (const Vec3& p : points_around(mesh, 1500, 3)) {
    const double expected = brute_force_distance(mesh, p);
    const PointDistance d = query.nearest_point(p, ws);
    const double tol = kRelTol * std::max(size, p.norm());
    ASSERT_NEAR(d.distance, expected, tol) << "p = " << p.transpose();
    ASSERT_NEAR((d.nearest - p).norm(), expected, tol);
    ASSERT_GE(d.triangle, 0);
    ASSERT_NEAR(reference_triangle_distance(mesh, static_cast<std::size_t>(d.triangle), p), expected, tol);
  }
}

TEST_P(BruteForceSegments, AgreeWithTernarySearch) {
  const TriangleMesh mesh = perturbed_tube();
  const DistanceQuery query(mesh, GetParam().options);
  DistanceWorkspace ws = query.make_workspace();
  ws.warm_start = GetParam().warm_start;
  const double tol = kRelTol * mesh_size(mesh);
  int crossing = 0;
  for (const auto& [a, b] : sample_segments(mesh)) {
    const double expected = brute_force_segment_distance(mesh, a, b);
    const CapsuleDistance c = query.capsule_distance(a, b, 0.0, ws);
    ASSERT_NEAR(c.axis_distance, expected, tol) << "a = " << a.transpose() << ", b = " << b.transpose();
    ASSERT_NEAR((c.on_mesh - c.on_segment).norm(), c.axis_distance, tol);
    crossing += c.axis_crosses_wall ? 1 : 0;
  }
  EXPECT_GT(crossing, 5) << "the sample should include segments through the wall";
}

const Variant kDirectVariants[] = {
    {"aabb_mean", {DistanceBv::kAabb, DistanceSplit::kMean, DistanceTraversal::kDirect}, true},
    {"aabb_mean_cold", {DistanceBv::kAabb, DistanceSplit::kMean, DistanceTraversal::kDirect}, false},
    {"aabb_bvcenter", {DistanceBv::kAabb, DistanceSplit::kBvCenter, DistanceTraversal::kDirect}, true},
    {"rss_median", {DistanceBv::kRss, DistanceSplit::kMedian, DistanceTraversal::kDirect}, true},
    {"obbrss_mean_cold", {DistanceBv::kObbRss, DistanceSplit::kMean, DistanceTraversal::kDirect}, false}};
const Variant kFclVariants[] = {
    {"fcl_rss", {DistanceBv::kRss, DistanceSplit::kMean, DistanceTraversal::kFcl}, true},
    {"fcl_obbrss_cold", {DistanceBv::kObbRss, DistanceSplit::kMean, DistanceTraversal::kFcl}, false}};

std::string variant_name(const ::testing::TestParamInfo<Variant>& param_info) { return param_info.param.name; }

INSTANTIATE_TEST_SUITE_P(Direct, BruteForcePoints, ::testing::ValuesIn(kDirectVariants), variant_name);
INSTANTIATE_TEST_SUITE_P(Fcl, BruteForcePoints, ::testing::ValuesIn(kFclVariants), variant_name);
// Segments: the direct traversal only; FCL's segment path is approximate (FclSegments below).
INSTANTIATE_TEST_SUITE_P(Direct, BruteForceSegments, ::testing::ValuesIn(kDirectVariants), variant_name);

// FCL's own path for segments (GJK on a radius-0 capsule) is approximate: GJK on the flat Minkowski difference of
// a segment and a triangle can stop early. This checks the kFcl wiring (shape pose, frames, point order) against
// the exact path: a wiring error costs millimetres, GJK's early stop here ≤ 1e-7 m (measured 7.7e-8 on this
// sample; on the real airway it is worse, see distance_query.cpp).
TEST(FclSegments, CloseToTheExactDistance) {
  constexpr double kGjkTol = 1e-6;  // 0.02 % of the tube radius; 10× the worst GJK error seen on this sample
  const TriangleMesh mesh = perturbed_tube();
  const DistanceQuery exact(mesh);
  const DistanceQuery gjk(mesh, {DistanceBv::kRss, DistanceSplit::kMean, DistanceTraversal::kFcl});
  DistanceWorkspace ws_exact = exact.make_workspace(), ws_gjk = gjk.make_workspace();
  int crossing = 0;
  for (const auto& [a, b] : sample_segments(mesh)) {
    const CapsuleDistance e = exact.capsule_distance(a, b, 0.0, ws_exact);
    const CapsuleDistance f = gjk.capsule_distance(a, b, 0.0, ws_gjk);
    EXPECT_NEAR(f.axis_distance, e.axis_distance, kGjkTol) << "a = " << a.transpose() << ", b = " << b.transpose();
    if (f.axis_crosses_wall) {
      EXPECT_TRUE(f.on_mesh.hasNaN());  // documented: FCL gives no points for a collision
      ++crossing;
    } else {
      EXPECT_NEAR((f.on_mesh - f.on_segment).norm(), f.axis_distance, kGjkTol);
    }
  }
  EXPECT_GT(crossing, 5);
}

// ---- Bad input and degenerate meshes -------------------------------------------------------------------------

TEST(DistanceQuery, RejectsBadMeshes) {
  EXPECT_THROW(DistanceQuery(TriangleMesh{}), InputError);
  TriangleMesh nan_vertex = tube();
  nan_vertex.vertices[5].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(DistanceQuery{nan_vertex}, InputError);
  TriangleMesh bad_index = tube();
  bad_index.triangles[3][1] = static_cast<std::uint32_t>(bad_index.vertices.size());
  try {
    DistanceQuery q(bad_index);
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(DistanceQuery(tube(), {DistanceBv::kAabb, DistanceSplit::kMean, DistanceTraversal::kFcl}),
               std::invalid_argument);
}

TEST(DistanceQuery, PointsOnTheSurfaceAndZeroAreaTriangles) {
  // A unit right triangle in z = 0 plus a zero-area sliver along x = 2 (collinear corners (2,0), (2,1), (2,2)).
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {2, 1, 0}, {2, 2, 0}};
  mesh.triangles = {{0, 1, 2}, {3, 4, 5}};
  const DistanceQuery query(mesh);
  DistanceWorkspace ws = query.make_workspace();
  constexpr double tol = kRelTol * 3.0;
  // On a vertex and inside the face: exactly on the mesh.
  EXPECT_NEAR(query.nearest_point(Vec3(1, 0, 0), ws).distance, 0.0, tol);
  EXPECT_NEAR(query.nearest_point(Vec3(0.2, 0.3, 0), ws).distance, 0.0, tol);
  // Beside the sliver: it acts as the segment x = 2, 0 ≤ y ≤ 2.
  const PointDistance d = query.nearest_point(Vec3(2.5, 1.5, 0.5), ws);
  EXPECT_NEAR(d.distance, std::sqrt(0.5), tol);
  EXPECT_TRUE(close(d.nearest, Vec3(2, 1.5, 0), 0.0, tol));
  EXPECT_EQ(d.triangle, 1);
  // Beyond the sliver's end.
  EXPECT_NEAR(query.nearest_point(Vec3(2, 3, 0), ws).distance, 1.0, tol);
  // A segment lying in the face's plane across an edge touches it: distance 0.
  EXPECT_NEAR(query.capsule_distance(Vec3(0.2, 0.2, 0), Vec3(0.2, -1, 0), 0.1, ws).axis_distance, 0.0, tol);
}

// ---- Workspace, warm start, threads --------------------------------------------------------------------------

/// Bitwise equality of two distance results: a determinism check, so exact comparison is the point.
bool same_bits(const PointDistance& a, const PointDistance& b) {
  return std::memcmp(&a.distance, &b.distance, sizeof(double)) == 0 &&
         std::memcmp(a.nearest.data(), b.nearest.data(), 3 * sizeof(double)) == 0 && a.triangle == b.triangle;
}

TEST(DistanceWorkspace, WarmStartGivesTheSameDistances) {
  // A coherent sequence (points marching along the tube) queried warm and cold: same distances; the reported
  // nearest point may differ only where several are equally near.
  const DistanceQuery query(tube());
  DistanceWorkspace warm = query.make_workspace(), cold = query.make_workspace();
  cold.warm_start = false;
  for (int i = 0; i < 400; ++i) {
    const Vec3 p = 2e-3 * radial(0.05 * i) + Vec3(0, 0, 0.0002 * i + 0.001);
    const PointDistance w = query.nearest_point(p, warm), c = query.nearest_point(p, cold);
    ASSERT_NEAR(w.distance, c.distance, kTubeTol) << "i = " << i;
    const CapsuleDistance wc = query.capsule_distance(p, p + Vec3(0, 1e-3, 1e-3), 0.5e-3, warm);
    const CapsuleDistance cc = query.capsule_distance(p, p + Vec3(0, 1e-3, 1e-3), 0.5e-3, cold);
    ASSERT_NEAR(wc.distance, cc.distance, kTubeTol) << "i = " << i;
  }
}

TEST(DistanceWorkspace, ReusedWithAnotherQuery) {
  // One workspace used with two hierarchies (the second deeper, so its stack must grow; the first's hint must
  // not leak into the second).
  const TriangleMesh small = perturbed_tube(), big = tube();
  const DistanceQuery q_small(small), q_big(big);
  ASSERT_GT(q_big.tree_depth(), q_small.tree_depth());
  DistanceWorkspace ws;
  for (const Vec3& p : points_around(small, 30, 13)) {
    ASSERT_NEAR(q_small.nearest_point(p, ws).distance, brute_force_distance(small, p), kRelTol * std::max(0.03, p.norm()));
    ASSERT_NEAR(q_big.nearest_point(p, ws).distance, brute_force_distance(big, p), kRelTol * std::max(kLength, p.norm()));
  }
}

TEST(DistanceQuery, ThreadsWithTheirOwnWorkspacesAgree) {
  // Two threads query one object concurrently, each with its own workspace, and must reproduce the serial run
  // bit for bit (both traversals: FCL's included).
  const TriangleMesh mesh = tube();
  const std::vector<Vec3> points = points_around(mesh, 2000, 17);
  for (const DistanceQueryOptions& options :
       {DistanceQueryOptions{}, DistanceQueryOptions{DistanceBv::kRss, DistanceSplit::kMean, DistanceTraversal::kFcl}}) {
    const DistanceQuery query(mesh, options);
    const auto run = [&](std::vector<PointDistance>& out) {
      DistanceWorkspace ws = query.make_workspace();
      for (std::size_t i = 0; i < points.size(); ++i) out[i] = query.nearest_point(points[i], ws);
    };
    std::vector<PointDistance> serial(points.size()), first(points.size()), second(points.size());
    run(serial);
    std::thread t1(run, std::ref(first)), t2(run, std::ref(second));
    t1.join();
    t2.join();
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_TRUE(same_bits(first[i], serial[i])) << i;
      ASSERT_TRUE(same_bits(second[i], serial[i])) << i;
    }
  }
}

}  // namespace
}  // namespace magvine::anatomy
