// Area, volume and bounding box of the parametric tube against the prism it is (exact) and the cylinder it
// approximates (closed form πdL, πr²L, with the polygon error bound as tolerance).

#include <gtest/gtest.h>

#include <cmath>

#include "magvine/anatomy/primitives.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

constexpr double kRoundoff = 1e-10;  // relative: sums of up to ~4e5 double terms (square-ish triangles)

TEST(TriangleMesh, OpenTubeAreaIsPrismAreaAndApproachesPiDL) {
  const TubeSpec spec{.radius = 4e-3, .length = 0.08, .segments = 256, .rings = 0, .capped = false};
  const TriangleMesh tube = make_tube(spec);
  const double n = spec.segments;
  const double prism = n * 2.0 * spec.radius * std::sin(kPi / n) * spec.length;
  EXPECT_NEAR(surface_area(tube), prism, kRoundoff * prism);
  // Inscribed polygon: perimeter deficit 1 − sin(x)/x ≤ x²/6 with x = π/n.
  const double cylinder = kPi * 2.0 * spec.radius * spec.length;
  const double polygon_bound = std::pow(kPi / n, 2) / 6.0;
  EXPECT_NEAR(surface_area(tube), cylinder, polygon_bound * cylinder);
  EXPECT_GT(std::abs(surface_area(tube) - cylinder), 0.0);  // it is a polygon, not the cylinder
}

TEST(TriangleMesh, CappedTubeVolumeIsPrismVolumeAndApproachesPiR2L) {
  const TubeSpec spec{.radius = 9e-3, .length = 0.12, .segments = 200, .rings = 7, .capped = true};
  const TriangleMesh tube = make_tube(spec);
  const double n = spec.segments;
  const double prism = 0.5 * n * spec.radius * spec.radius * std::sin(2.0 * kPi / n) * spec.length;
  EXPECT_NEAR(signed_volume(tube), prism, kRoundoff * prism);  // positive: outward normals
  const double cylinder = kPi * spec.radius * spec.radius * spec.length;
  // Polygon area deficit 1 − sin(2x)/(2x) ≤ (2x)²/6 with x = π/n.
  EXPECT_NEAR(signed_volume(tube), cylinder, std::pow(2.0 * kPi / n, 2) / 6.0 * cylinder);
  const double caps = 2.0 * 0.5 * n * spec.radius * spec.radius * std::sin(2.0 * kPi / n);
  const double wall = n * 2.0 * spec.radius * std::sin(kPi / n) * spec.length;
  EXPECT_NEAR(surface_area(tube), wall + caps, kRoundoff * (wall + caps));
}

TEST(TriangleMesh, VolumeIsTranslationInvariantFarFromOrigin) {
  // CT meshes live in scanner coordinates (~1 m from the origin); the volume must not lose digits there.
  TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.05, .segments = 64, .rings = 0, .capped = true});
  const double v0 = signed_volume(tube);
  for (Vec3& p : tube.vertices) p += Vec3(0.3, -0.2, 1.15);
  EXPECT_NEAR(signed_volume(tube), v0, 1e-9 * v0);  // 1e-9: cancellation over ~1e3 terms at 1 m / 5 mm scale
}

TEST(TriangleMesh, FlipOrientationNegatesVolume) {
  TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.05, .segments = 32, .rings = 0, .capped = true});
  const double v0 = signed_volume(tube);
  flip_orientation(tube);
  EXPECT_NEAR(signed_volume(tube), -v0, kRoundoff * v0);
}

TEST(TriangleMesh, BoundingBoxOfTube) {
  const TriangleMesh tube = make_tube({.radius = 5e-3, .length = 0.05, .segments = 64, .rings = 0, .capped = true});
  const Aabb box = bounding_box(tube);
  EXPECT_NEAR(box.min.x(), -5e-3, 1e-15);
  EXPECT_NEAR(box.max.y(), 5e-3 * std::sin(2.0 * kPi * 16 / 64), 1e-15);
  EXPECT_NEAR(box.min.z(), 0.0, 1e-15);
  EXPECT_NEAR(box.max.z(), 0.05, 1e-15);
  EXPECT_EQ(bounding_box(TriangleMesh{}).max, Vec3::Zero());
}

}  // namespace
}  // namespace magvine::anatomy
