// CollisionWorld: sphere/capsule contacts, ray casts and inside/outside against analytic references (a finely
// triangulated plane, a folded sheet, the polygonal tube of make_tube), plus the no-allocation contract.

#include "magvine/anatomy/collision_world.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "support/compare.hpp"

// ---- Allocation counter: every global operator new in this executable. ----
namespace {
std::atomic<long> g_allocations{0};
void* counted_malloc(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n == 0 ? 1 : n);
}
// Not inlined, so GCC does not pair the replaced operator delete's free() with operator new (-Wmismatched-new-delete).
[[gnu::noinline]] void plain_free(void* p) { std::free(p); }
void* counted_aligned(std::size_t n, std::size_t alignment) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t size = (n + alignment - 1) / alignment * alignment;
  return std::aligned_alloc(alignment, size == 0 ? alignment : size);
}
}  // namespace

void* operator new(std::size_t n) {
  if (void* p = counted_malloc(n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return counted_malloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return counted_malloc(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  if (void* p = counted_aligned(n, static_cast<std::size_t>(a))) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p) noexcept { plain_free(p); }
void operator delete[](void* p) noexcept { plain_free(p); }
void operator delete(void* p, std::size_t) noexcept { plain_free(p); }
void operator delete[](void* p, std::size_t) noexcept { plain_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { plain_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { plain_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { plain_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { plain_free(p); }

namespace magvine::anatomy {
namespace {

using magvine::test::close;

// Coordinates are millimetre-scale in metres; double rounding on them is ~1e-18 m per operation and a few hundred
// operations per contact, so 1e-15 m would do; 1e-12 m leaves margin and is still 1e6 below the smallest geometric
// term tested (the 64-gon sag R(1 − cos π/64) = 6e-6 m).
constexpr double kLengthTol = 1e-12;
// Unit normals from normalised cross products of the same coordinates: rounding ~1e-16; the snag failure this
// guards against tilts a normal by O(1) (an edge or vertex normal instead of the face normal).
constexpr double kNormalTol = 1e-12;

constexpr double kMm = kMmToM;

/// Flat square grid of n×n cells of size h in z = height, centred on the origin, two triangles per cell
/// (diagonal from (i, j) to (i+1, j+1)), counter-clockwise seen from +z (normals +z). fold(x) adds a height.
template <class Fold>
TriangleMesh make_grid(int n, double h, Fold fold) {
  TriangleMesh mesh;
  const double x0 = -0.5 * n * h;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = x0 + i * h;
      mesh.vertices.emplace_back(x, x0 + j * h, fold(x));
    }
  }
  const auto at = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return mesh;
}

TriangleMesh make_plane(int n, double h) {
  return make_grid(n, h, [](double) { return 0.0; });
}

/// Roof along the y axis: z = −tan(θ)·|x|, the crease (x = 0) a column of vertices (n even).
TriangleMesh make_roof(int n, double h, double theta) {
  return make_grid(n, h, [theta](double x) { return -std::tan(theta) * std::abs(x); });
}

CollisionWorld outside_world(const TriangleMesh& mesh) {
  return CollisionWorld(mesh, CollisionWorldOptions{.free_side = FreeSide::kOutside});
}

// ---------------------------------------------------------------------------------------------------------------
// Flat plane of 20×20 cells (800 triangles), bodies above it (free side = outside = +z).

class PlaneTest : public ::testing::Test {
 protected:
  static constexpr int kCells = 20;
  static constexpr double kCell = 1.0 * kMm;
  PlaneTest() : world(outside_world(make_plane(kCells, kCell))) {}

  /// One contact, normal +z, depth r − z, point below the centre.
  void expect_plane_contact(const Vec3& c, double r) {
    std::array<Contact, 16> out;
    const std::size_t n = world.sphere_contacts(c, r, out);
    ASSERT_EQ(n, 1u) << "at " << c.transpose();
    EXPECT_TRUE(close(out[0].normal, Vec3::UnitZ(), 0.0, kNormalTol)) << "at " << c.transpose();
    EXPECT_NEAR(out[0].depth, r - c.z(), kLengthTol);
    EXPECT_TRUE(close(out[0].point, Vec3(c.x(), c.y(), 0.0), 0.0, kLengthTol));
  }

  CollisionWorld world;
};

TEST_F(PlaneTest, StatsSeeAFlatOpenSheet) {
  EXPECT_EQ(world.stats().triangles, 800u);
  EXPECT_EQ(world.stats().degenerate_triangles, 0u);
  EXPECT_EQ(world.stats().ridge_edges, 0u);  // coplanar neighbours: no edge is a feature
  EXPECT_EQ(world.stats().boundary_edges, 4u * kCells);
}

TEST_F(PlaneTest, SphereOnFaceEdgeAndVertexGetsThePlaneNormal) {
  const double r = 2.0 * kMm;  // covers ~50 triangles: every shared edge and vertex under it could snag
  const double z = 0.7 * kMm;
  expect_plane_contact({0.3 * kMm, 0.6 * kMm, z}, r);                  // face interior
  expect_plane_contact({0.5 * kMm, 0.0, z}, r);                        // on a cell edge (shared by two triangles)
  expect_plane_contact({0.5 * kMm, 0.5 * kMm, z}, r);                  // on a diagonal
  expect_plane_contact({0.0, 0.0, z}, r);                              // on a vertex shared by six triangles
  expect_plane_contact({1e-15, -1e-15, z}, r);                         // rounding-level off the vertex
  expect_plane_contact({2.0 * kMm, 3.0 * kMm, 1e-3 * kMm}, r);        // nearly flush
  expect_plane_contact({-1.0 * kMm, 1.0 * kMm, -0.5 * kMm}, r);       // centre behind the wall: depth r + 0.5 mm
}

TEST_F(PlaneTest, SlidingSphereNeverSnags) {
  // Along the diagonal y = x (through vertices and along diagonal edges) and along a cell edge line, at varying
  // heights: always one contact with the exact plane normal and depth.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> height(0.05 * kMm, 1.45 * kMm);
  const double r = 1.5 * kMm;
  for (int i = 0; i <= 400; ++i) {
    const double s = -4.0 * kMm + 8.0 * kMm * i / 400.0;
    expect_plane_contact({s, s, height(rng)}, r);
    expect_plane_contact({s, 1.0 * kMm, height(rng)}, r);
  }
}

TEST_F(PlaneTest, SphereAboveReachOrWhollyBehindTouchesNothing) {
  std::array<Contact, 4> out;
  EXPECT_EQ(world.sphere_contacts({0.1 * kMm, 0.2 * kMm, 1.0 * kMm}, 1.0 * kMm, out), 0u);   // just touching
  EXPECT_EQ(world.sphere_contacts({0.1 * kMm, 0.2 * kMm, -1.2 * kMm}, 1.0 * kMm, out), 0u);  // wholly behind
}

TEST_F(PlaneTest, BoundaryEdgeActsAsAKnifeEdge) {
  // Beyond the rim x = +10 mm, above the sheet: the normal points from the rim line to the centre.
  const double rim = 0.5 * kCells * kCell;
  const double r = 1.0 * kMm;
  std::array<Contact, 4> out;
  const Vec3 c(rim + 0.3 * kMm, 0.25 * kMm, 0.4 * kMm);
  ASSERT_EQ(world.sphere_contacts(c, r, out), 1u);
  const Vec3 q(rim, c.y(), 0.0);
  EXPECT_TRUE(close(out[0].normal, Vec3((c - q).normalized()), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - (c - q).norm(), kLengthTol);
  EXPECT_TRUE(close(out[0].point, q, 0.0, kLengthTol));
  // Beyond the rim and below the sheet's plane: the normal is clamped to the in-plane direction leaving the sheet.
  const Vec3 below(rim + 0.3 * kMm, 0.25 * kMm, -0.4 * kMm);
  ASSERT_EQ(world.sphere_contacts(below, r, out), 1u);
  EXPECT_TRUE(close(out[0].normal, Vec3::UnitX(), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - 0.3 * kMm, kLengthTol);
}

TEST(CollisionWorldSides, InsideFreeSideMirrorsThePlane) {
  // Default free side (inside, against the +z normals): bodies live below the sheet and are pushed down.
  const CollisionWorld world(make_plane(20, 1.0 * kMm));
  const double r = 1.0 * kMm;
  std::array<Contact, 4> out;
  ASSERT_EQ(world.sphere_contacts({0.2 * kMm, 0.1 * kMm, -0.4 * kMm}, r, out), 1u);
  EXPECT_TRUE(close(out[0].normal, Vec3(-Vec3::UnitZ()), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - 0.4 * kMm, kLengthTol);
  // A centre that crossed to the outer side is still pushed back to the free side, deeper than r.
  ASSERT_EQ(world.sphere_contacts({0.2 * kMm, 0.1 * kMm, 0.4 * kMm}, r, out), 1u);
  EXPECT_TRUE(close(out[0].normal, Vec3(-Vec3::UnitZ()), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r + 0.4 * kMm, kLengthTol);
  EXPECT_EQ(world.sphere_contacts({0.2 * kMm, 0.1 * kMm, 1.4 * kMm}, r, out), 0u);
}

// ---------------------------------------------------------------------------------------------------------------
// Folded sheet z = −tan θ·|x|: a ridge seen from above (free side outside), a valley seen from below (inside).

constexpr double kFold = 0.3;  // [rad] bend of the crease

TEST(FoldedSheet, InfoMapClassifiesTheCrease) {
  const TriangleMesh roof = make_roof(20, 1.0 * kMm, kFold);
  // 20 crease edges, each seen from the triangle on either side.
  EXPECT_EQ(outside_world(roof).stats().ridge_edges, 40u);
  EXPECT_EQ(CollisionWorld(roof).stats().ridge_edges, 0u);  // from below the crease is a valley
}

TEST(FoldedSheet, RidgeGivesTheFeatureNormalInsideItsCone) {
  const CollisionWorld world = outside_world(make_roof(20, 1.0 * kMm, kFold));
  const Vec3 left_normal(-std::sin(kFold), 0.0, std::cos(kFold));  // face normals of x < 0 and x > 0
  const Vec3 right_normal(std::sin(kFold), 0.0, std::cos(kFold));
  const double r = 1.5 * kMm;
  std::array<Contact, 8> out;
  for (int i = -60; i <= 60; ++i) {
    const Vec3 c(0.02 * kMm * i, 0.37 * kMm, 0.8 * kMm);
    ASSERT_EQ(world.sphere_contacts(c, r, out), 1u) << "x = " << c.x();
    const Vec3 crease(0.0, c.y(), 0.0);
    const Vec3 to_centre = c - crease;
    if (std::abs(c.x()) <= std::tan(kFold) * c.z()) {
      // Inside the crease's cone of normals: the nearest wall point is on the crease.
      EXPECT_TRUE(close(out[0].normal, Vec3(to_centre.normalized()), 0.0, kNormalTol)) << "x = " << c.x();
      EXPECT_NEAR(out[0].depth, r - to_centre.norm(), kLengthTol);
      EXPECT_TRUE(close(out[0].point, crease, 0.0, kLengthTol));
    } else {
      const Vec3& n = c.x() < 0.0 ? left_normal : right_normal;
      EXPECT_TRUE(close(out[0].normal, n, 0.0, kNormalTol)) << "x = " << c.x();
      EXPECT_NEAR(out[0].depth, r - n.dot(to_centre), kLengthTol);
    }
  }
}

TEST(FoldedSheet, ValleyGivesOnlyFaceNormals) {
  // From below, the crease is a valley: a sphere in it touches both faces, never the crease itself.
  const CollisionWorld world(make_roof(20, 1.0 * kMm, kFold));
  const Vec3 left_free(std::sin(kFold), 0.0, -std::cos(kFold));
  const Vec3 right_free(-std::sin(kFold), 0.0, -std::cos(kFold));
  const double r = 1.5 * kMm;
  std::array<Contact, 8> out;
  for (int i = -50; i <= 50; ++i) {
    const Vec3 c(0.01 * kMm * i, -0.21 * kMm, -1.0 * kMm);
    const std::size_t n = world.sphere_contacts(c, r, out);
    ASSERT_GE(n, 1u);
    for (std::size_t k = 0; k < n; ++k) {
      const bool left = (out[k].normal - left_free).norm() <= kNormalTol;
      const bool right = (out[k].normal - right_free).norm() <= kNormalTol;
      ASSERT_TRUE(left || right) << "spurious normal " << out[k].normal.transpose() << " at x = " << c.x();
      const Vec3& nf = left ? left_free : right_free;
      const double plane_offset = 0.0;  // both planes pass through the crease line (x = 0, z = 0)
      EXPECT_NEAR(out[k].depth, r - (nf.dot(c) - plane_offset), kLengthTol);
    }
  }
  // On the bisector both faces are reached: exactly two contacts, equally deep.
  ASSERT_EQ(world.sphere_contacts({0.0, 0.1 * kMm, -1.0 * kMm}, r, out), 2u);
  EXPECT_NEAR(out[0].depth, out[1].depth, kLengthTol);
}

// ---------------------------------------------------------------------------------------------------------------
// Closed tube of make_tube: R = 5 mm, 64 segments. Its wall is a regular 64-gon prism: a face centred at angle
// φ_m = (i + ½)·2π/n lies at the apothem R_eff = R·cos(π/n) from the axis.

class TubeTest : public ::testing::Test {
 protected:
  static constexpr int kSegments = 64;
  static constexpr double kRadius = 5.0 * kMm;
  static constexpr double kLength = 50.0 * kMm;
  TubeTest() : world(make_tube({.radius = kRadius, .length = kLength, .segments = kSegments})) {}

  static double apothem() { return kRadius * std::cos(kPi / kSegments); }
  /// Angle of the centre of the face strip containing angle φ.
  static double face_angle(double phi) {
    const double step = 2.0 * kPi / kSegments;
    return (std::floor(phi / step) + 0.5) * step;
  }
  static Vec3 radial(double phi) { return {std::cos(phi), std::sin(phi), 0.0}; }

  CollisionWorld world;
};

TEST_F(TubeTest, StatsSeeAClosedConvexLumen) {
  EXPECT_EQ(world.stats().boundary_edges, 0u);
  EXPECT_EQ(world.stats().ridge_edges, 0u);  // from inside every bend of a convex prism is a valley
}

TEST_F(TubeTest, SphereDepthMatchesThePolygon) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * kPi);
  std::uniform_real_distribution<double> along(10.0 * kMm, 40.0 * kMm);
  std::uniform_real_distribution<double> offset(3.6 * kMm, 5.3 * kMm);  // > R/2: one face strip reaches the centre
  const double r = 1.5 * kMm;
  // The smooth-cylinder answer r + d − R differs from the polygon's by at most the sag (R + d)(1 − cos π/n).
  const double sag_tol = (kRadius + 5.3 * kMm) * (1.0 - std::cos(kPi / kSegments));
  std::array<Contact, 8> out;
  for (int i = 0; i < 500; ++i) {
    const double phi = i == 0 ? face_angle(0.1) : angle(rng);  // the first exactly at a face centre
    const double d = offset(rng);
    const Vec3 c = d * radial(phi) + Vec3(0, 0, along(rng));
    const double phi_m = face_angle(phi);
    const double expected = r + d * std::cos(phi - phi_m) - apothem();
    if (expected <= 0.0) continue;
    ASSERT_EQ(world.sphere_contacts(c, r, out), 1u) << "phi = " << phi << " d = " << d;
    EXPECT_NEAR(out[0].depth, expected, kLengthTol);
    EXPECT_NEAR(out[0].depth, r + d - kRadius, sag_tol);
    EXPECT_TRUE(close(out[0].normal, Vec3(-radial(phi_m)), 0.0, kNormalTol));  // toward the axis
    EXPECT_NEAR(out[0].point.dot(radial(phi_m)), apothem(), kLengthTol);       // on the face plane
  }
}

TEST_F(TubeTest, CentredSphereTouchesNothingAndEscapedSphereDoesNot) {
  std::array<Contact, 8> out;
  EXPECT_EQ(world.sphere_contacts({0.0, 0.0, 25.0 * kMm}, 4.0 * kMm, out), 0u);
  EXPECT_EQ(world.sphere_contacts({0.0, 0.0, 25.0 * kMm}, 4.9 * kMm, out), 0u);  // apothem 4.994 mm
  // Wholly outside the wall: no contact (contains() is what notices an escaped body).
  EXPECT_EQ(world.sphere_contacts(7.0 * kMm * radial(0.2) + Vec3(0, 0, 25.0 * kMm), 1.0 * kMm, out), 0u);
}

TEST_F(TubeTest, CapCornerTouchesWallAndCap) {
  const double phi = face_angle(1.0);
  const double r = 1.0 * kMm;
  const Vec3 c = 4.5 * kMm * radial(phi) + Vec3(0, 0, 0.6 * kMm);
  std::array<Contact, 8> out;
  ASSERT_EQ(world.sphere_contacts(c, r, out), 2u);
  // Deepest first: the cap (depth 0.4 mm), then the wall (0.5 mm − sag)... compare as a set.
  const Contact& cap = out[0].normal.z() > 0.5 ? out[0] : out[1];
  const Contact& wall = out[0].normal.z() > 0.5 ? out[1] : out[0];
  EXPECT_TRUE(close(cap.normal, Vec3::UnitZ(), 0.0, kNormalTol));
  EXPECT_NEAR(cap.depth, r - 0.6 * kMm, kLengthTol);
  EXPECT_TRUE(close(wall.normal, Vec3(-radial(phi)), 0.0, kNormalTol));
  EXPECT_NEAR(wall.depth, r + 4.5 * kMm - apothem(), kLengthTol);
  EXPECT_GE(out[0].depth, out[1].depth);
}

TEST_F(TubeTest, OutsideFreeSideSeesTheTubeAsAnObstacle) {
  const CollisionWorld outside(make_tube({.radius = kRadius, .length = kLength, .segments = kSegments}),
                               CollisionWorldOptions{.free_side = FreeSide::kOutside});
  // From outside the wall's vertical edges (between face strips, over rings − 1 bands) and the two rim circles are
  // ridges, each counted from both triangles; diagonals, ring edges and cap fan edges are flat.
  const std::size_t rings = (outside.mesh().vertices.size() - 2) / kSegments;
  EXPECT_EQ(outside.stats().ridge_edges, 2u * kSegments * (rings - 1) + 4u * kSegments);
  // From outside, the 64-gon's vertical edges are ridges: a sphere facing a vertex gets a radial normal.
  const double phi = 2.0 * kPi * 5 / kSegments;  // vertex angle
  const double r = 1.0 * kMm;
  const Vec3 c = (kRadius + 0.6 * kMm) * radial(phi) + Vec3(0, 0, 25.3 * kMm);
  std::array<Contact, 8> out;
  ASSERT_EQ(outside.sphere_contacts(c, r, out), 1u);
  EXPECT_TRUE(close(out[0].normal, radial(phi), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - 0.6 * kMm, kLengthTol);
}

// ---------------------------------------------------------------------------------------------------------------
// Capsules.

TEST_F(PlaneTest, TiltedCapsuleTouchesAtItsLowerEnd) {
  const double r = 1.0 * kMm;
  std::array<Contact, 8> out;
  const Vec3 a(-0.7 * kMm, 0.3 * kMm, 0.2 * kMm);
  const Vec3 b(1.1 * kMm, -0.4 * kMm, 0.9 * kMm);
  for (const auto& [p, q] : {std::pair{a, b}, std::pair{b, a}}) {
    ASSERT_EQ(world.capsule_contacts(p, q, r, out), 1u);
    EXPECT_TRUE(close(out[0].normal, Vec3::UnitZ(), 0.0, kNormalTol));
    EXPECT_NEAR(out[0].depth, r - a.z(), kLengthTol);
    EXPECT_TRUE(close(out[0].point, Vec3(a.x(), a.y(), 0.0), 0.0, kLengthTol));
  }
  // Crossing the wall: the end behind it sets the depth (one-sided wall).
  const Vec3 low(0.4 * kMm, 0.3 * kMm, -0.3 * kMm);
  ASSERT_EQ(world.capsule_contacts(low, b, r, out), 1u);
  EXPECT_NEAR(out[0].depth, r + 0.3 * kMm, kLengthTol);
  // Lying flat at height h: depth r − h.
  ASSERT_EQ(world.capsule_contacts({-2.0 * kMm, 0.5 * kMm, 0.4 * kMm}, {3.0 * kMm, 0.5 * kMm, 0.4 * kMm}, r, out),
            1u);
  EXPECT_TRUE(close(out[0].normal, Vec3::UnitZ(), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - 0.4 * kMm, kLengthTol);
}

TEST_F(PlaneTest, ZeroLengthCapsuleIsASphere) {
  const Vec3 c(0.5 * kMm, 0.5 * kMm, 0.3 * kMm);
  std::array<Contact, 4> sphere;
  std::array<Contact, 4> capsule;
  ASSERT_EQ(world.sphere_contacts(c, 1.0 * kMm, sphere), 1u);
  ASSERT_EQ(world.capsule_contacts(c, c, 1.0 * kMm, capsule), 1u);
  EXPECT_NEAR(capsule[0].depth, sphere[0].depth, kLengthTol);
  EXPECT_TRUE(close(capsule[0].normal, sphere[0].normal, 0.0, kNormalTol));
}

TEST_F(TubeTest, CapsuleAlongAndAcrossTheWall) {
  const double phi_m = face_angle(2.0);
  const double r = 1.0 * kMm;
  std::array<Contact, 8> out;
  // Parallel to the axis at offset d toward a face centre.
  const double d = 4.3 * kMm;
  ASSERT_EQ(world.capsule_contacts(d * radial(phi_m) + Vec3(0, 0, 20 * kMm), d * radial(phi_m) + Vec3(0, 0, 22 * kMm),
                                   r, out),
            1u);
  EXPECT_NEAR(out[0].depth, r + d - apothem(), kLengthTol);
  EXPECT_TRUE(close(out[0].normal, Vec3(-radial(phi_m)), 0.0, kNormalTol));
  // Tilted in the radial plane: the end nearer the wall is deepest.
  const Vec3 inner = 3.8 * kMm * radial(phi_m) + Vec3(0, 0, 30 * kMm);
  const Vec3 outer = 4.6 * kMm * radial(phi_m) + Vec3(0, 0, 31.5 * kMm);
  ASSERT_EQ(world.capsule_contacts(inner, outer, r, out), 1u);
  EXPECT_NEAR(out[0].depth, r + 4.6 * kMm - apothem(), kLengthTol);
  EXPECT_NEAR(out[0].point.z(), outer.z(), kLengthTol);
  // On the axis, shorter than the tube: nothing.
  EXPECT_EQ(world.capsule_contacts({0, 0, 10 * kMm}, {0, 0, 40 * kMm}, 3.0 * kMm, out), 0u);
}

TEST(FoldedSheet, CapsuleOverTheRidgeGetsTheCreaseContact) {
  const CollisionWorld world = outside_world(make_roof(20, 1.0 * kMm, kFold));
  // A capsule lying across the crease (along x) at height h touches the crease line: normal +z, depth r − h.
  const double r = 1.0 * kMm;
  const double h = 0.6 * kMm;
  std::array<Contact, 8> out;
  ASSERT_EQ(world.capsule_contacts({-1.0 * kMm, 0.3 * kMm, h}, {1.2 * kMm, 0.3 * kMm, h}, r, out), 1u);
  EXPECT_TRUE(close(out[0].normal, Vec3::UnitZ(), 0.0, kNormalTol));
  EXPECT_NEAR(out[0].depth, r - h, kLengthTol);
  EXPECT_TRUE(close(out[0].point, Vec3(0.0, 0.3 * kMm, 0.0), 0.0, kLengthTol));
}

// ---------------------------------------------------------------------------------------------------------------
// Rays.

TEST_F(TubeTest, RayHitsTheWallAtThePolygonDistance) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * kPi);
  for (int i = 0; i < 200; ++i) {
    const double phi = angle(rng);
    const double phi_m = face_angle(phi);
    const Vec3 origin(0.0, 0.0, 17.0 * kMm);
    const auto hit = world.ray_cast(origin, radial(phi), 1.0);
    ASSERT_TRUE(hit.has_value());
    EXPECT_NEAR(hit->distance, apothem() / std::cos(phi - phi_m), kLengthTol);
    EXPECT_TRUE(close(hit->point, Vec3(origin + hit->distance * radial(phi)), 0.0, kLengthTol));
    EXPECT_TRUE(close(hit->normal, Vec3(-radial(phi_m)), 0.0, kNormalTol));  // toward the origin
    EXPECT_FALSE(hit->front_face);                                           // hit from inside
  }
  // Exactly at a vertex (on the circle) and at the midpoint of a ring edge (on the apothem): inclusive, still hits.
  const double step = 2.0 * kPi / kSegments;
  const auto vertex_hit = world.ray_cast({0.0, 0.0, 20.0 * kMm}, radial(9 * step), 1.0);
  ASSERT_TRUE(vertex_hit.has_value());
  EXPECT_NEAR(vertex_hit->distance, kRadius, kLengthTol);
  const std::size_t rings = (world.mesh().vertices.size() - 2) / kSegments;
  const double ring_z = kLength * 40.0 / static_cast<double>(rings - 1);  // the height of ring 40
  const auto edge_hit = world.ray_cast({0.0, 0.0, ring_z}, radial(9.5 * step), 1.0);
  ASSERT_TRUE(edge_hit.has_value());
  EXPECT_NEAR(edge_hit->distance, apothem(), kLengthTol);
  // Along the axis: the top cap, seen from inside.
  const auto cap = world.ray_cast({0.1 * kMm, 0.2 * kMm, 20.0 * kMm}, Vec3::UnitZ(), 1.0);
  ASSERT_TRUE(cap.has_value());
  EXPECT_NEAR(cap->distance, kLength - 20.0 * kMm, kLengthTol);
  EXPECT_TRUE(close(cap->normal, Vec3(-Vec3::UnitZ()), 0.0, kNormalTol));
}

TEST_F(TubeTest, RayMissesReturnNothing) {
  const Vec3 origin(0.0, 0.0, 20.0 * kMm);
  EXPECT_FALSE(world.ray_cast(origin, radial(0.3), 0.9 * apothem()).has_value());  // too short
  EXPECT_FALSE(world.ray_cast({10 * kMm, 0, 20 * kMm}, Vec3::UnitX(), 1.0).has_value());  // outside, going away
  const auto from_outside = world.ray_cast({10 * kMm, 0, 20 * kMm}, -Vec3::UnitX(), 1.0);
  ASSERT_TRUE(from_outside.has_value());
  EXPECT_TRUE(from_outside->front_face);
  EXPECT_NEAR(from_outside->distance, 10 * kMm - kRadius, kLengthTol);  // the x axis meets a vertex column
}

// ---------------------------------------------------------------------------------------------------------------
// Inside/outside.

TEST_F(TubeTest, ContainsByParityVote) {
  EXPECT_TRUE(world.contains({0.0, 0.0, 25.0 * kMm}));
  EXPECT_TRUE(world.contains({0.0, 0.0, 0.01 * kMm}));
  EXPECT_TRUE(world.contains(0.999 * apothem() * radial(face_angle(0.4)) + Vec3(0, 0, 3 * kMm)));
  EXPECT_FALSE(world.contains(1.001 * kRadius * radial(0.4) + Vec3(0, 0, 3 * kMm)));
  EXPECT_FALSE(world.contains({0.0, 0.0, -0.01 * kMm}));
  EXPECT_FALSE(world.contains({0.0, 0.0, kLength + 0.01 * kMm}));
  EXPECT_FALSE(world.contains({1.0, 2.0, 3.0}));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 300; ++i) {
    const Vec3 p(8 * kMm * u(rng), 8 * kMm * u(rng), kLength * (0.5 + 0.6 * u(rng)));
    const double phi = std::atan2(p.y(), p.x());
    const bool inside_polygon = std::hypot(p.x(), p.y()) * std::cos(phi - face_angle(phi)) < apothem();
    const bool expected = inside_polygon && p.z() > 0.0 && p.z() < kLength;
    EXPECT_EQ(world.contains(p), expected) << p.transpose();
  }
}

TEST_F(TubeTest, ContainsSurvivesRaysThroughVerticesAndEdges) {
  // Place points so that the first parity ray passes exactly (up to rounding) through a vertex or the midpoint of
  // an edge: that ray is ambiguous and must not decide the vote.
  const Vec3 dir = CollisionWorld::parity_directions()[0];
  const TriangleMesh& mesh = world.mesh();
  int checked = 0;
  for (std::size_t t = 100; t < 400; t += 37) {
    const Triangle& tri = mesh.triangles[t];
    const Vec3& v = mesh.vertices[tri[0]];
    const Vec3 edge_mid = 0.5 * (mesh.vertices[tri[0]] + mesh.vertices[tri[1]]);
    for (const Vec3& target : {v, edge_mid}) {
      for (const double s : {0.5 * kMm, 2.0 * kMm}) {
        // The ray from p along dir meets `target` after s; p is inside or outside depending on the wall's angle.
        const Vec3 p = target - s * dir;
        const double rho = std::hypot(p.x(), p.y());
        if (rho < 0.95 * apothem() && p.z() > 0 && p.z() < kLength) {
          EXPECT_TRUE(world.contains(p)) << p.transpose();
          ++checked;
        } else if (rho > 1.05 * kRadius || p.z() < 0 || p.z() > kLength) {
          EXPECT_FALSE(world.contains(p)) << p.transpose();
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 10);
}

// ---------------------------------------------------------------------------------------------------------------
// Output handling, input errors, allocation.

TEST(FoldedSheet, FullSpanKeepsTheDeepestContact) {
  const CollisionWorld world(make_roof(20, 1.0 * kMm, kFold));  // valley seen from below: two face contacts
  const Vec3 c(0.05 * kMm, 0.1 * kMm, -1.0 * kMm);
  std::array<Contact, 8> all;
  ASSERT_EQ(world.sphere_contacts(c, 1.5 * kMm, all), 2u);
  EXPECT_GT(all[0].depth, all[1].depth);  // sorted deepest first
  std::array<Contact, 1> one;
  ASSERT_EQ(world.sphere_contacts(c, 1.5 * kMm, one), 1u);
  EXPECT_NEAR(one[0].depth, all[0].depth, kLengthTol);
  EXPECT_EQ(world.sphere_contacts(c, 1.5 * kMm, std::span<Contact>()), 0u);
}

TEST(FoldedSheet, MergeAngleMergesNearbyNormals) {
  // With a merge angle above the fold's 2θ, the valley's two faces become one (the deepest) contact.
  const CollisionWorld world(make_roof(20, 1.0 * kMm, kFold), CollisionWorldOptions{.merge_angle = 2.5 * kFold});
  std::array<Contact, 8> out;
  EXPECT_EQ(world.sphere_contacts({0.05 * kMm, 0.1 * kMm, -1.0 * kMm}, 1.5 * kMm, out), 1u);
}

TEST(CollisionWorldInput, RejectsBadMeshesAndOptions) {
  EXPECT_THROW(CollisionWorld(TriangleMesh{}), InputError);
  TriangleMesh bad_index = make_plane(2, 1.0 * kMm);
  bad_index.triangles[3][1] = 1000;
  EXPECT_THROW(CollisionWorld{bad_index}, InputError);
  TriangleMesh nan_vertex = make_plane(2, 1.0 * kMm);
  nan_vertex.vertices[4].x() = std::nan("");
  EXPECT_THROW(CollisionWorld{nan_vertex}, InputError);
  EXPECT_THROW(CollisionWorld(make_plane(2, 1.0 * kMm), CollisionWorldOptions{.merge_angle = 2.0}), InputError);
}

TEST(CollisionWorldInput, DegenerateTrianglesAreIgnored) {
  TriangleMesh mesh = make_plane(4, 1.0 * kMm);
  mesh.triangles.push_back({0, 1, 2});  // collinear corners on the first grid row
  const CollisionWorld world(mesh, CollisionWorldOptions{.free_side = FreeSide::kOutside});
  EXPECT_EQ(world.stats().degenerate_triangles, 1u);
  std::array<Contact, 4> out;
  ASSERT_EQ(world.sphere_contacts({-1.5 * kMm, -1.9 * kMm, 0.2 * kMm}, 0.5 * kMm, out), 1u);
  EXPECT_TRUE(close(out[0].normal, Vec3::UnitZ(), 0.0, kNormalTol));
}

TEST_F(TubeTest, CachedSphereContactsEqualTheUncached) {
  // A cache too small to hold the neighbourhood is bypassed (every query walks the tree), a large one is used;
  // both give the uncached contacts exactly (the same triangles, order and arithmetic), so == is the right test.
  const CollisionWorld other(make_tube({.radius = kRadius, .length = kLength, .segments = 32}));
  ContactCache small(0.5 * kMm, 4);
  ContactCache large(0.5 * kMm);
  std::array<Contact, 8> plain;
  std::array<Contact, 8> cached;
  int hits = 0;
  for (int i = 0; i < 400; ++i) {
    // A node sliding along the wall in 0.1 mm steps, 0.5–1.3 mm from it; every 50th query on another world.
    const double phi = 0.002 * i;
    const Vec3 c = (apothem() - 0.5 * kMm - 0.8 * kMm * std::sin(0.05 * i)) * radial(phi) + Vec3(0, 0, 20 * kMm);
    const CollisionWorld& w = i % 50 == 49 ? other : world;
    const std::size_t n = w.sphere_contacts(c, 1.5 * kMm, plain);
    hits += n > 0 ? 1 : 0;
    for (ContactCache* cache : {&small, &large}) {
      const std::size_t m = w.sphere_contacts(c, 1.5 * kMm, cached, *cache);
      ASSERT_EQ(m, n) << "query " << i;
      for (std::size_t k = 0; k < n; ++k) {
        EXPECT_TRUE(cached[k].point == plain[k].point && cached[k].normal == plain[k].normal &&
                    cached[k].depth == plain[k].depth && cached[k].triangle == plain[k].triangle)
            << "query " << i << ", contact " << k;
      }
    }
  }
  EXPECT_GT(hits, 200);
  EXPECT_FALSE(small.filled());
  EXPECT_TRUE(large.filled());
  EXPECT_THROW(ContactCache(-1e-3), InputError);
}

TEST_F(TubeTest, CachedNearTrianglesEqualTheUncached) {
  // NearCache: a node sliding along the wall, its query radius changing as a squeezed radius would, answered from the
  // kept neighbourhood and refilled as it moves out; a cache too small for the neighbourhood is bypassed. Either way
  // the answer is the uncached one, bit for bit (the same triangles and arithmetic, nearest first and ties by index),
  // so == is the right test; and the kept neighbourhood must answer most queries, or it spares nothing.
  const CollisionWorld other(make_tube({.radius = kRadius, .length = kLength, .segments = 32}));
  NearCache small(0.1 * kMm, 2);
  NearCache large(0.1 * kMm);
  std::array<NearTriangle, 4> plain;  // fewer than the triangles in reach at times: the nearest four kept
  std::array<NearTriangle, 4> cached;
  int found = 0;
  for (int i = 0; i < 2000; ++i) {
    const double phi = 0.0005 * i;
    const Vec3 c = (apothem() - 1.52 * kMm - 0.1 * kMm * std::sin(0.01 * i)) * radial(phi) + Vec3(0, 0, 20 * kMm);
    const double r = (i % 7 == 3 ? 1.45 : 1.55) * kMm;
    const CollisionWorld& w = i % 500 == 499 ? other : world;
    const std::size_t n = w.triangles_within(c, r, plain);
    found += n > 0 ? 1 : 0;
    for (NearCache* cache : {&small, &large}) {
      const std::size_t m = w.triangles_within(c, r, cached, *cache);
      ASSERT_EQ(m, n) << "query " << i;
      for (std::size_t k = 0; k < std::min(n, plain.size()); ++k) {
        EXPECT_TRUE(cached[k].point == plain[k].point && cached[k].distance == plain[k].distance &&
                    cached[k].triangle == plain[k].triangle)
            << "query " << i << ", triangle " << k;
      }
    }
  }
  EXPECT_GT(found, 1000);
  EXPECT_GT(large.hits(), 10 * large.fills());
  EXPECT_THROW(NearCache(-1e-3), InputError);

  // A cache filled in a world since destroyed is refilled in the next, even one built where the first one lay (the
  // allocator often reuses the address): worlds are told apart by an id, not a pointer.
  NearCache kept(0.5 * kMm);
  const Vec3 c = (apothem() - 1.5 * kMm) * radial(0.3) + Vec3(0, 0, 20 * kMm);
  {
    const CollisionWorld gone(make_tube({.radius = kRadius + 0.3 * kMm, .length = kLength, .segments = 40}));
    EXPECT_EQ(gone.triangles_within(c, 1.55 * kMm, cached, kept), 0u);  // that tube's wall is out of reach
  }
  const CollisionWorld next(make_tube({.radius = kRadius, .length = kLength, .segments = 64}));
  const std::size_t n = next.triangles_within(c, 1.55 * kMm, plain);
  ASSERT_GT(n, 0u);
  EXPECT_EQ(next.triangles_within(c, 1.55 * kMm, cached, kept), n);
}

TEST_F(TubeTest, NearTrianglesStopAtTheFirstWithinTheStopDistance) {
  // stop_within: a point with a triangle that close gets a partial answer led by such a triangle (the barrier refuses
  // it whatever else lies near); a point without one gets the whole answer, as if no stop were asked.
  NearCache cache(0.1 * kMm);
  std::array<NearTriangle, 16> plain;
  std::array<NearTriangle, 16> stopped;
  int partial = 0;
  int whole = 0;
  for (int i = 0; i < 400; ++i) {
    const double phi = 0.002 * i;
    const Vec3 c = (apothem() - 1.5 * kMm + 0.6 * kMm * std::sin(0.05 * i)) * radial(phi) + Vec3(0, 0, 20 * kMm);
    const double r = 1.55 * kMm;
    const double stop = 1.4 * kMm;
    const std::size_t n = world.triangles_within(c, r, plain);
    const std::size_t m = world.triangles_within(c, r, stopped, cache, stop);
    if (n > 0 && plain[0].distance <= stop) {
      ++partial;
      ASSERT_GE(m, 1u) << "query " << i;
      EXPECT_LE(stopped[0].distance, stop) << "query " << i;
    } else {
      ++whole;
      ASSERT_EQ(m, n) << "query " << i;
      for (std::size_t k = 0; k < std::min(n, plain.size()); ++k) {
        EXPECT_TRUE(stopped[k].distance == plain[k].distance && stopped[k].triangle == plain[k].triangle)
            << "query " << i << ", triangle " << k;
      }
    }
  }
  EXPECT_GT(partial, 50);
  EXPECT_GT(whole, 50);
}

TEST(CollisionWorldAllocation, QueriesDoNotAllocate) {
  const CollisionWorld world(make_tube({.radius = 5.0 * kMm, .length = 50.0 * kMm, .segments = 64}));
  std::array<Contact, 16> out;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> points(512);
  for (Vec3& p : points) p = Vec3(4.5 * kMm * u(rng), 4.5 * kMm * u(rng), 25 * kMm + 24 * kMm * u(rng));
  std::size_t contacts = 0;
  int inside = 0;
  ContactCache cache(0.3 * kMm);
  NearCache near_cache(0.3 * kMm);
  std::array<NearTriangle, 8> near;
  const auto run = [&] {
    for (std::size_t i = 0; i + 1 < points.size(); ++i) {
      contacts += world.sphere_contacts(points[i], 1.5 * kMm, out);
      contacts += world.sphere_contacts(points[i], 1.5 * kMm, out, cache);                            // refill
      contacts += world.sphere_contacts(points[i] + Vec3(0, 0, 0.1 * kMm), 1.5 * kMm, out, cache);  // cached
      contacts += world.capsule_contacts(points[i], points[i + 1], 1.0 * kMm, out);
      contacts += world.triangles_within(points[i], 1.5 * kMm, near);
      contacts += world.triangles_within(points[i], 1.5 * kMm, near, near_cache);                            // refill
      contacts += world.triangles_within(points[i] + Vec3(0, 0, 0.1 * kMm), 1.4 * kMm, near, near_cache);  // cached
      if (world.ray_cast(points[i], (points[i + 1] - points[i]).normalized(), 0.1).has_value()) ++inside;
      if (i % 8 == 0 && world.contains(points[i])) ++inside;
    }
  };
  run();  // warm-up
  const long before = g_allocations.load();
  run();
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0) << "allocations during queries";
  EXPECT_GT(contacts, 100u);  // the loop did real work
  EXPECT_GT(inside, 100);
}

}  // namespace
}  // namespace magvine::anatomy
