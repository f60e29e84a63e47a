// Wall contact that obeys statics (robot/growth.hpp, docs/growth-and-contact.md): the wall
// forces of a converged step against closed forms. A vine grown head-on into a tube's end cap presses it with the
// growth law's own force (P − Y)·πR² (Blumenschein et al. 2017: at stall the obstacle carries what the yield does
// not); a vine lying in a horizontal tube rests its weight on the wall.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/robot/vine.hpp"
#include "support/tube_world.hpp"

namespace magvine::robot {
namespace {

using Tube = test::TubeWorld;

TEST(WallStatics, AVineGrownHeadOnIntoAWallPressesItWithTheGrowthForce) {
  // The thesis's Ø5 mm fluid vine in a Ø8 mm, 60 mm capped tube, constant yield Y = 20 kPa (no length or turning
  // terms), no gravity: at three pressures the cap carries (P − Y)·πR², R the extended radius. Tolerance 5 %: the
  // growth law's viscous term k·e of the last step's extension (k = πR²/(K dt)) is what is left of the approach.
  anatomy::TubeParams tp;
  tp.diameter = 8e-3;
  tp.length = 60e-3;
  const Tube tube(tp);
  for (const double pressure : {27e3, 31e3, 35e3}) {
    GrowthOptions o = GrowthOptions{};
    o.gravity = Vec3::Zero();
    o.law.yield_pressure = 20e3;
    o.law.length_yield = 0.0;
    o.law.turning_yield = 0.0;
    VineGrowth g(thesis_fluid_vine(10e-3), o, &tube.world, {}, Vec3(2e-3, 0.0, 0.0), Mat3::Identity());
    for (int step = 0; step < 600 && g.time() < 30.0; ++step) {
      const GrowthStatus r = g.advance(0.05, {.pressure = pressure});
      ASSERT_TRUE(r.converged) << r.failure << " at step " << step;
      for (const Vec3& x : g.state().x) ASSERT_TRUE(tube.world.contains(x)) << "a node left the lumen";
    }
    const double expected = (pressure - 20e3) * kPi * g.radius() * g.radius();
    const WallForces& f = g.wall_forces();
    const double carried = f.normal_vector.back().x();
    std::printf("  %.0f kPa: tip at %.2f mm (cap 60 mm), cap carries %.4f N, (P - Y)piR^2 = %.4f N, length %.1f mm\n",
                pressure / 1e3, 1e3 * g.state().tip().x(), carried, expected, 1e3 * g.length());
    for (const GrowthEvent& e : g.events()) {
      std::printf("    %.1f mm: %s: %s\n", 1e3 * e.length, std::string(growth_event_name(e.kind)).c_str(),
                  e.detail.c_str());
    }
    EXPECT_NEAR(carried, expected, 0.05 * expected);
  }
}

TEST(WallStatics, AVineLyingInAHorizontalTubeRestsItsWeightOnTheWall) {
  // The Ø5 mm fluid vine grown to 100 mm (the tether) along a Ø8 mm horizontal tube under gravity: the wall's
  // normal forces add up to the weight the clamp does not carry, ±3 % (the bound; a tube's floor facets tilt
  // the normals by up to 2.8°). The weight is ρA(L − h/2)g (half the first edge sits on the clamp); the clamp's share
  // comes from the first edge's internal force. Every step balances globally to 1e-3 of its largest load.
  anatomy::TubeParams tp;
  tp.diameter = 8e-3;
  tp.length = 150e-3;
  const Tube tube(tp);
  GrowthOptions o = GrowthOptions{};
  o.law.yield_pressure = 20e3;
  VineGrowth g(thesis_fluid_vine(10e-3), o, &tube.world, {}, Vec3(2e-3, 0.0, 0.0), Mat3::Identity());
  while (g.time() < 12.0) {
    const GrowthStatus r = g.advance(0.05, {.pressure = 35e3, .tether_length = 100e-3});
    ASSERT_TRUE(r.converged) << r.failure << " at " << g.time() << " s, " << 1e3 * g.length() << " mm";
    const WallForces& f = g.wall_forces();
    ASSERT_LE(f.imbalance.norm(), 1e-3 * f.largest_load) << "at " << 1e3 * g.length() << " mm";
  }
  const WallForces& f = g.wall_forces();
  const double weight = g.model().mass_per_length * (g.model().length - 0.5 * g.edge_length()) * 9.81;
  const double rests = weight - f.clamp.z();
  std::printf(
      "  length %.1f mm, weight %.4f N, clamp carries %.4f N, wall normal forces %.4f N (rests with %.4f N), "
      "%d nodes in contact\n",
      1e3 * g.length(), weight, f.clamp.z(), f.total_normal, rests, f.nodes_in_contact);
  EXPECT_NEAR(g.length(), 100e-3, 1e-6);
  EXPECT_GT(f.nodes_in_contact, 20);
  EXPECT_NEAR(f.total_normal, rests, 0.03 * rests);
  // The film lying on the wall presses it with its pressure (film_contact_pressure: a few mN per node spread over
  // F/P, far from filling the patch).
  for (std::size_t i = 1; i < f.normal.size(); ++i) {
    if (f.normal[i] > 0.0) {
      EXPECT_NEAR(f.pressure[i], 35e3, 1e-9) << "node " << i;
    }
  }
  EXPECT_NEAR(f.max_pressure, 35e3, 1e-9);
}

TEST(WallStatics, AMagnetPressingAVineOnAWallIsBalancedByTheWallsReaction) {
  // The Ø5 mm magnetic-fluid vine, 60 mm along a Ø8 mm tube without gravity, the thesis's EPM (Ø101.6 mm N52) 90 mm
  // below the tube pulling it onto the floor: the wall's reaction balances the magnetic force less the clamp's
  // share, ±2 %. The magnetic force comes from the field at the edges, the wall's from the barrier's gaps, the
  // clamp's from the first edge's stress: three laws, one balance.
  anatomy::TubeParams tp;
  tp.diameter = 8e-3;
  tp.length = 100e-3;
  const Tube tube(tp);
  magnetics::FieldModel epm;
  epm.add(magnetics::CylinderMagnet(50.8e-3, 101.6e-3, Vec3(0.0, 0.0, 1.48)),
          magnetics::Pose::from_axis(Vec3(40e-3, 0.0, -90e-3), Vec3::UnitZ()), "EPM");
  GrowthOptions o = GrowthOptions{};
  o.gravity = Vec3::Zero();
  o.law.yield_pressure = 20e3;
  VineGrowth g(thesis_fluid_vine(10e-3), o, &tube.world, field_function(epm, epm.rest_poses), Vec3(2e-3, 0.0, 0.0),
               Mat3::Identity());
  while (g.time() < 8.0) {
    const GrowthStatus r = g.advance(0.05, {.pressure = 35e3, .tether_length = 60e-3});
    ASSERT_TRUE(r.converged) << r.failure;
  }
  const WallForces& f = g.wall_forces();
  Vec3 wall = Vec3::Zero();
  for (const Vec3& n : f.normal_vector) wall -= n;
  for (const Vec3& s : f.shear_vector) wall -= s;
  const Vec3 magnetic = body_load(g.model(), field_function(epm, epm.rest_poses), g.state());
  std::printf("  magnetic force %.4f N down, clamp %.4f N, wall reaction %.4f N up, %d nodes in contact\n",
              -magnetic.z(), f.clamp.z(), wall.z(), f.nodes_in_contact);
  EXPECT_GT(-magnetic.z(), 0.01);
  EXPECT_GT(f.nodes_in_contact, 5);
  EXPECT_NEAR(wall.z(), -(magnetic.z() + f.clamp.z()), 0.02 * std::abs(magnetic.z()));
}

TEST(WallStatics, EveryStepPastTheCarinaBalancesAndNoNodeLeavesTheLumen) {
  // The Ø5 mm fluid vine grown 100 mm from 70 mm down the generated tree's trachea, past the carina into a main
  // bronchus (bench_growth's /carina case), gravity across it: every converged step balances globally to 1e-3 of its
  // largest load, and every node stays inside the lumen at every step.
  anatomy::BronchialTreeParams p;
  p.max_generation = 4;
  p.spacing = 0.5e-3;
  const anatomy::Phantom tree = anatomy::make_bronchial_tree(p);
  const anatomy::CollisionWorld world(tree.mesh);
  Mat3 frame;
  frame.col(0) = -Vec3::UnitZ();
  frame.col(1) = Vec3::UnitX();
  frame.col(2) = frame.col(0).cross(frame.col(1));
  GrowthOptions o = GrowthOptions{};
  o.gravity = Vec3(9.81, 0.0, 0.0);
  o.law.yield_pressure = 20e3;
  VineGrowth g(thesis_fluid_vine(5e-3), o, &world, {}, Vec3(3e-3, 0.0, -70e-3), frame);
  double worst = 0.0;
  int steps = 0;
  while (g.length() < 105e-3 && g.time() < 30.0) {
    const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
    ASSERT_TRUE(r.converged) << r.failure << " at " << g.time() << " s";
    ++steps;
    const WallForces& f = g.wall_forces();
    worst = std::max(worst, f.imbalance.norm() / f.largest_load);
    ASSERT_LE(f.imbalance.norm(), 1e-3 * f.largest_load) << "at " << g.time() << " s";
    for (const Vec3& x : g.state().x) ASSERT_TRUE(world.contains(x)) << "a node left the lumen at " << g.time() << " s";
  }
  std::printf("  %d steps to %.1f mm, tip at (%.1f, %.1f, %.1f) mm, worst imbalance %.2g of the largest load\n", steps,
              1e3 * g.length(), 1e3 * g.state().tip().x(), 1e3 * g.state().tip().y(), 1e3 * g.state().tip().z(), worst);
  EXPECT_GE(g.length(), 105e-3);
  EXPECT_LT(g.state().tip().z(), -0.12);  // past the carina (the generated trachea is 120 mm long)
}

}  // namespace
}  // namespace magvine::robot
