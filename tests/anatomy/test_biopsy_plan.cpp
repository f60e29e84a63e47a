// The biopsy planner (anatomy/biopsy_plan.hpp) on geometry with known answers: a straight tube with a nodule beside
// it (the shortest needle path under the angle limit in closed form), a tool too wide for the tube, a second airway
// in the way (checked against the brute-force segment distance of tests/support), and a needle too short.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "magvine/anatomy/biopsy_plan.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "support/mesh_distance.hpp"

namespace magvine::anatomy {
namespace {

constexpr double kR = 6e-3;  // tube radius [m]

/// A capped tube of radius 6 mm along +x from x = 0 to 120 mm (256 facets round: its wall is within 0.5 µm of the
/// cylinder), with a centreline node every 0.5 mm.
struct Tube {
  TriangleMesh mesh;
  AirwayGraph graph;
};

Tube tube(const Vec3& offset = Vec3::Zero()) {
  Tube t;
  t.mesh = make_tube({.radius = kR, .length = 0.12, .segments = 256, .rings = 240, .capped = true});
  for (Vec3& v : t.mesh.vertices) v = Vec3(v.z(), v.x(), v.y()) + offset;  // make_tube runs along z: turn it to x
  std::vector<std::uint32_t> nodes;
  for (int k = 0; k <= 230; ++k) nodes.push_back(add_node(t.graph, offset + Vec3(0.0025 + 0.0005 * k, 0, 0), kR));
  add_branch(t.graph, -1, nodes);
  return t;
}

// Nodule 26 mm from the axis (20 mm outside the wall) at x = 60 mm. At a stop x the needle leaves at angle θ to the
// axis, tan θ = 26 / (60 − x), and runs (26 − 6) mm / sin θ through tissue: shortest at the largest allowed θ. With
// the 60° limit: x* = 60 − 26/tan 60° = 44.99 mm and 23.094 mm of needle; the nearest node on the allowed side lies
// within 0.5 mm, where the needle is at most 0.2 mm longer. With 90°: straight across, 20 mm.
TEST(BiopsyPlan, ShortestNeedleUnderTheAngleLimitInATube) {
  const Tube t = tube();
  const CollisionWorld world(t.mesh);
  const Vec3 nodule(0.06, 0.026, 0.0);
  const BiopsyPlan p = plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3, .needle_tolerance = 0.0});
  ASSERT_TRUE(p.found) << p.why;
  EXPECT_LE(p.angle, std::numbers::pi / 3.0);
  EXPECT_NEAR(p.start.x(), 0.06 - 0.026 / std::tan(std::numbers::pi / 3.0), 0.5e-3);
  EXPECT_GE(p.needle, 0.020 / std::sin(std::numbers::pi / 3.0) - 1e-6);
  EXPECT_LE(p.needle, 0.020 / std::sin(std::numbers::pi / 3.0) + 0.2e-3);
  EXPECT_NEAR(p.wall.y(), kR * p.direction.y() / std::hypot(p.direction.y(), p.direction.z()), 1e-5);

  // With the default 1 mm tolerance: the straightest stop whose needle is at most 1 mm longer. The needle 20/sin θ
  // grows by 1 mm from θ = 60° to θ = 50.4° (20/sin θ = 24.094 mm), the stop moving back to x = 60 − 26/tan θ.
  const BiopsyPlan easy = plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3});
  ASSERT_TRUE(easy.found);
  EXPECT_LE(easy.needle, p.needle + 1e-3);
  const double theta = std::asin(0.020 / (0.020 / std::sin(std::numbers::pi / 3.0) + 1e-3));
  EXPECT_NEAR(easy.angle, theta, 0.5 * kDegToRad);
  EXPECT_NEAR(easy.start.x(), 0.06 - 0.026 / std::tan(theta), 0.5e-3);

  const BiopsyPlan across =
      plan_biopsy(t.graph, world, nodule,
                  {.tool_radius = 2.5e-3, .max_angle = std::numbers::pi / 2 + 1e-6, .needle_tolerance = 0.0});
  ASSERT_TRUE(across.found);
  EXPECT_NEAR(across.needle, 0.020, 1e-5);
  EXPECT_NEAR(across.start.x(), 0.06, 0.25e-3 + 1e-9);
}

// A tip that cannot turn points down the tube (+x): its ray passes the nodule 26 mm from the axis at 26 mm, from
// every stop before x = 60 mm; a nodule 4 mm off the axis 10 mm past the tube's end is missed by 4 mm. The plan's
// own stop (x ≈ 45 mm, ray along +x) misses by 26 mm too. straight_miss against its closed form: a point behind the
// ray is its distance to the start.
TEST(BiopsyPlan, ReportsHowFarATipThatCannotTurnMisses) {
  EXPECT_NEAR(straight_miss(Vec3::Zero(), Vec3::UnitX(), Vec3(0.01, 0.003, 0.004)), 0.005, 1e-15);
  EXPECT_NEAR(straight_miss(Vec3::Zero(), Vec3::UnitX(), Vec3(-0.003, 0.004, 0.0)), 0.005, 1e-15);
  const Tube t = tube();
  const CollisionWorld world(t.mesh);
  const BiopsyPlan beside = plan_biopsy(t.graph, world, Vec3(0.06, 0.026, 0.0), {.tool_radius = 2.5e-3});
  ASSERT_TRUE(beside.found);
  EXPECT_NEAR(beside.straight_miss, 0.026, 1e-9);
  EXPECT_NEAR(beside.best_straight_miss, 0.026, 1e-9);
  EXPECT_EQ(beside.best_straight_branch, 0);
  const BiopsyPlan ahead =
      plan_biopsy(t.graph, world, Vec3(0.13, 0.004, 0.0), {.tool_radius = 2.5e-3, .max_angle = std::numbers::pi / 2});
  ASSERT_TRUE(ahead.found) << ahead.why;
  EXPECT_NEAR(ahead.best_straight_miss, 0.004, 1e-9);
  EXPECT_NEAR(ahead.straight_miss, 0.004, 1e-9);  // the stop's own ray runs down the axis too
}

// A given stop (a planning problem's start pose on the wall): its nearest node the tool fits to is the stop, taken
// as given. Pose on the wall at x = 30 mm, y = 6 mm: the node (30, 0, 0), 6 mm from it; the needle towards the
// nodule (60, 26, 0) leaves at θ = atan(26/30) to the axis and runs √(30² + 26²) − 6/sin θ = 30.54 mm in tissue. A
// pose at x = 55 mm, where the needle must turn 79°, beyond the 60° limit, is still taken.
TEST(BiopsyPlan, AGivenStopIsTakenAtItsNearestNode) {
  const Tube t = tube();
  const CollisionWorld world(t.mesh);
  const Vec3 nodule(0.06, 0.026, 0.0);
  const BiopsyPlan p = plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3, .stop = Vec3(0.03, kR, 0.0)});
  ASSERT_TRUE(p.found) << p.why;
  EXPECT_NEAR(p.start.x(), 0.03, 1e-12);
  EXPECT_NEAR(p.given_distance, kR, 1e-12);
  const double theta = std::atan2(0.026, 0.030);
  EXPECT_NEAR(p.angle, theta, 1e-9);
  EXPECT_NEAR(p.needle, std::hypot(0.030, 0.026) - kR / std::sin(theta), 1e-5);  // the 256-gon's wall: 0.5 µm
  EXPECT_FALSE(p.crosses_airway);
  const BiopsyPlan steep = plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3, .stop = Vec3(0.055, 0, 0)});
  ASSERT_TRUE(steep.found) << steep.why;
  EXPECT_NEAR(steep.angle, std::atan2(0.026, 0.005), 1e-9);
  // A nodule in the lumen seen from the given stop: refused, saying why.
  const BiopsyPlan in_lumen =
      plan_biopsy(t.graph, world, Vec3(0.09, 0.001, 0.0), {.tool_radius = 2.5e-3, .stop = Vec3(0.03, 0, 0)});
  EXPECT_FALSE(in_lumen.found);
  EXPECT_NE(in_lumen.why.find("inside the lumen"), std::string::npos) << in_lumen.why;
}

// A tool wider than the lumen reaches no node; a needle limit below 20 mm rules every stop out as too long.
TEST(BiopsyPlan, SaysWhyWhenNoStopWorks) {
  const Tube t = tube();
  const CollisionWorld world(t.mesh);
  const Vec3 nodule(0.06, 0.026, 0.0);
  const BiopsyPlan wide = plan_biopsy(t.graph, world, nodule, {.tool_radius = 6.5e-3});
  EXPECT_FALSE(wide.found);
  EXPECT_EQ(wide.reachable, 0u);
  EXPECT_NE(wide.why.find("0 centreline nodes reachable"), std::string::npos) << wide.why;
  const BiopsyPlan shortn = plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3, .max_needle = 0.019});
  EXPECT_FALSE(shortn.found);
  EXPECT_EQ(shortn.too_long + shortn.too_steep, shortn.reachable);
  // ... and how near a tip pointing down the tube comes: 26 mm (the nodule's offset from the axis).
  EXPECT_NE(shortn.why.find("passes the nodule's centre at 26.0 mm at best"), std::string::npos) << shortn.why;
  EXPECT_GT(shortn.too_long, 0u);
}

// A second airway (a tube along x at y = 16 mm from x = 90 mm on) between the first and a nodule at (100, 30) mm:
// the unobstructed plan (a stop near x = 83 mm, 27.7 mm of needle) crosses it. A path from a stop at x passes y = 22 mm
// (the second tube's far side) at x + (100 − x)·22/30, in front of its end at 90 mm only for x < 62.5 mm: at least
// 24 mm / sin(atan(30/37.5)) = 38.4 mm of needle. The plan's needle, from its wall exit to the nodule, keeps
// clear of every triangle (brute-force segment distance > 0), and stops whose paths cross it are counted.
TEST(BiopsyPlan, NeedleStaysOutsideOtherAirways) {
  const Tube t = tube();
  const Tube other = tube(Vec3(0.09, 0.016, 0.0));
  TriangleMesh both = t.mesh;
  const auto base = static_cast<std::uint32_t>(both.vertices.size());
  both.vertices.insert(both.vertices.end(), other.mesh.vertices.begin(), other.mesh.vertices.end());
  for (const Triangle& tri : other.mesh.triangles)
    both.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
  const CollisionWorld world(both);
  const Vec3 nodule(0.10, 0.030, 0.0);
  const BiopsyPlan p =
      plan_biopsy(t.graph, world, nodule, {.tool_radius = 2.5e-3, .max_needle = 0.08, .needle_tolerance = 0.0});
  ASSERT_TRUE(p.found) << p.why;
  EXPECT_GT(p.through_airway, 0u);
  const test::BruteForceDistance brute(both);
  EXPECT_GT(brute.segment(p.wall + 1e-6 * p.direction, nodule).distance, 0.0);
  // Without the second airway the same nodule is reached by a shorter needle: the detour has a cost.
  const BiopsyPlan free = plan_biopsy(t.graph, CollisionWorld(t.mesh), nodule,
                                      {.tool_radius = 2.5e-3, .max_needle = 0.08, .needle_tolerance = 0.0});
  EXPECT_NEAR(free.needle, 0.024 / std::sin(std::numbers::pi / 3.0), 0.2e-3);
  EXPECT_GE(p.needle, 0.024 / std::sin(std::atan(30.0 / 37.5)) - 0.2e-3);
  EXPECT_LT(p.start.x(), 0.0625);
}

}  // namespace
}  // namespace magvine::anatomy
