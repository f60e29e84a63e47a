// The biopsy needle (robot/needle.hpp, issue 31 item 2): a needle pushed out of a grown vine's tip into the wall in
// front of it. Its reaction is a load on the vine's tip that the body's equilibrium carries to the walls and the
// clamp; the global balance of every converged increment is the statics check. A puncture stiffer than what the
// body holds makes the tip slide back, and the report says so.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/error.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/robot/needle.hpp"
#include "magvine/robot/vine.hpp"
#include "support/tube_world.hpp"

namespace magvine::robot {
namespace {

using Tube = test::TubeWorld;

/// A tube of `diameter` capped at 60 mm.
anatomy::TubeParams capped_tube(double diameter) {
  anatomy::TubeParams p;
  p.diameter = diameter;
  p.length = 60e-3;
  return p;
}

struct Grown {
  GrowthModel model;
  GrowthState state;
  GrowthWorkspace ws;
};

/// The thesis's Ø5 mm fluid vine grown to `length` along a Ø8 mm tube capped at 60 mm, at 35 kPa, gravity −z.
Grown grow(const Tube& tube, double length, const Mat3& frame = Mat3::Identity()) {
  GrowthOptions o;
  o.law.yield_pressure = 20e3;
  Grown g{make_growth_model(thesis_fluid_vine(10e-3), o, &tube.world, Vec3(2e-3, 0.0, 0.0), frame), {}, {}};
  start_growth(g.model, {}, 10e-3, 35e3, g.state, g.ws);
  while (g.state.time < 10.0) {
    const GrowthStatus r = grow_step(g.model, {}, {.pressure = 35e3, .tether_length = length}, g.state, g.ws, 0.05);
    EXPECT_TRUE(r.converged) << r.failure;
    if (!r.converged) break;
  }
  return g;
}

TEST(Needle, TheTissueForceIsTheCuttingForcePlusShaftFriction) {
  NeedleTool n;
  n.cutting_force = 1.2;
  n.shaft_friction = 20.0;
  n.puncture_depth = 2e-3;
  EXPECT_EQ(needle_tissue_force(n, 0.0), 0.0);
  EXPECT_EQ(needle_tissue_force(n, -1e-3), 0.0);
  EXPECT_DOUBLE_EQ(needle_tissue_force(n, 0.5e-3), 1.2 * 0.25);  // the wall deflecting
  EXPECT_DOUBLE_EQ(needle_tissue_force(n, 2e-3), 1.2);           // punctured
  EXPECT_DOUBLE_EQ(needle_tissue_force(n, 5e-3), 1.2 + 20.0 * 3e-3);
  // Its potential and stiffness (the step's TipContact) are the force's integral from 0 and its slope: central
  // differences on either side of the puncture (1e-8 relative: round-off of the differences of a quadratic), and
  // the potential continuous where the contact starts and where the wall ruptures.
  EXPECT_NEAR(needle_tissue_law(n, 1e-9).potential, 0.0, 1e-15);
  EXPECT_NEAR(needle_tissue_law(n, 2e-3 - 1e-9).potential, needle_tissue_law(n, 2e-3).potential,
              1.01 * 1.2 * 1e-9);  // F_c·δ over the step δ, no jump
  for (const double d : {0.3e-3, 1.9e-3, 2.1e-3, 6e-3}) {
    const double e = 1e-7;
    const ContactLaw l = needle_tissue_law(n, d);
    EXPECT_NEAR(l.force, (needle_tissue_law(n, d + e).potential - needle_tissue_law(n, d - e).potential) / (2 * e),
                1e-8 * l.force + 1e-12)
        << d;
    EXPECT_NEAR(l.stiffness, (needle_tissue_force(n, d + e) - needle_tissue_force(n, d - e)) / (2 * e),
                1e-6 * l.stiffness)
        << d;
  }
  EXPECT_NEAR(needle_tissue_law(n, 2e-3).potential, 0.5 * 1.2 * 2e-3, 1e-15);  // ∫ of the rise: F_c·d_p/2
  n.length = 0.0;
  EXPECT_THROW(check_needle(n), InputError);
}

// The vine grown to 50 mm in a Ø5.6 mm tube capped at 60 mm, the nodule 15 mm beyond the cap on the axis: the lumen
// hugs the Ø5 mm vine up to its tip, the stabilisation the thesis found a biopsy needs (5.6.3: the force the vine
// delivers depends on a support close to the tip). In a Ø8 mm tube the same 1 N moves the tip back 0.26 mm instead
// of 0.013 mm and tilts it so the needle ends 5 mm off the axis (measured).
TEST(Needle, TheReactionOfAOneNewtonPunctureIsCarriedByTheWallsAndTheClamp) {
  const Tube tube(capped_tube(5.6e-3));
  Grown g = grow(tube, 50e-3);
  const Vec3 nodule(75e-3, 0.0, 0.0);
  NeedleTool n;
  const PunctureReport r = push_needle(g.model, {}, n, nodule, 3e-3, 35e3, g.state, g.ws);
  std::printf(
      "  wall %.2f mm ahead, target %.1f mm, held %d slide %.3f mm, needle tip %.2f mm from the nodule, "
      "max force %.2f N, walls take %.1f %%, imbalance %.2e, unsupported %.2e, largest moment %.3f of the collapse "
      "moment %s\n",
      1e3 * r.wall_distance, 1e3 * r.target_protrusion, r.held, 1e3 * r.slide, 1e3 * r.to_nodule, r.max_force,
      100.0 * r.wall_share, r.max_imbalance, r.max_unsupported, r.max_moment, r.why.c_str());
  EXPECT_TRUE(r.success) << r.why;
  // The wall is 8 mm ahead: the needle meets tissue there and the reaction is the cutting force from then on.
  EXPECT_NEAR(r.wall_distance, 8e-3, 0.1e-3);
  EXPECT_DOUBLE_EQ(r.max_force, 1.0);
  // It punctured: an increment's equilibrium put the needle's tip past d_p.
  EXPECT_TRUE(r.punctured);
  EXPECT_TRUE(std::any_of(r.steps.begin(), r.steps.end(),
                          [&](const PunctureStep& s) { return s.depth >= n.puncture_depth; }));
  int loaded = 0;
  for (const PunctureStep& s : r.steps) {
    EXPECT_DOUBLE_EQ(s.force, needle_tissue_force(n, s.depth));
    if (s.force == 0.0) continue;
    ++loaded;
    // Statics (the issue's ±2 %): the changes of the walls' (barrier and friction) and the clamp's forces on the
    // body take up the reaction (no field: nothing else changes), and the whole body balances to the solver's
    // tolerance. Three laws: the barrier's gaps, the friction's slips, the first edge's stress.
    EXPECT_LE(s.unsupported, 0.02) << "at " << 1e3 * s.protrusion << " mm";
    EXPECT_LE(s.imbalance, 1e-3) << "at " << 1e3 * s.protrusion << " mm";
  }
  EXPECT_GT(loaded, 20);
  // It holds: the tip gives way by the body's compliance only, far below the 2 mm limit, and the body stays below
  // the wrinkling moment πR³P/2 (1 N times the 0.3 mm clearance is 0.17 of the collapse moment; measured 0.08).
  EXPECT_LT(r.slide, 0.5e-3);
  EXPECT_GT(r.max_moment, 0.0);
  EXPECT_LT(r.max_moment, 0.5);
}

TEST(Needle, AStiffPunctureMakesTheTipSlideBack) {
  const Tube tube(capped_tube(5.6e-3));
  Grown g = grow(tube, 50e-3);
  NeedleTool n;
  // 8 N: eight times the thesis's design load. With rigid contact spheres the body in the Ø5.6 mm tube held 5 N
  // with its tip 0.13 mm back (under a dead load) and slid 2.8 mm at 8 N. With the film's flattening (2026-12-06)
  // it gives way before the wall ruptures: it holds at most 2.9–3.0 N within the 2 mm limit, then slides (2.3 mm
  // in one build, 12.7 mm in another: whether the reaction reaches 8 N as it slides turns on round-off, so the
  // rupture is not asserted).
  n.cutting_force = 8.0;
  const PunctureReport r = push_needle(g.model, {}, n, Vec3(75e-3, 0.0, 0.0), 3e-3, 35e3, g.state, g.ws);
  std::printf("  held %d slide %.3f mm, max force %.2f N, largest moment %.3f of the collapse moment: %s\n", r.held,
              1e3 * r.slide, r.max_force, r.max_moment, r.why.c_str());
  EXPECT_FALSE(r.held);
  EXPECT_FALSE(r.success);
  EXPECT_GT(r.slide, n.max_slide);
  // What it held within the slide limit stays below the wall's 8 N: the vine gave way first.
  EXPECT_GT(r.held_force, 1.0);
  EXPECT_LT(r.held_force, 8.0);
  EXPECT_NE(r.why.find("slid back"), std::string::npos) << r.why;
  // How it gives way: the body creases. A column pressed into a tube's clearance c = 0.3 mm bends by the load times
  // its offset, F·c, which reaches the inflated beam's collapse moment πR³P = 1.72 mN·m (R = 2.5 mm, 35 kPa) at
  // F = 5.7 N; with the flattened film a joint passes πR³P (the crease's hinge law, eq 4.13) before the wall
  // ruptures (1.19 and 1.76 of it in the two builds).
  EXPECT_GE(r.max_moment, 1.0);
}

// The loading path of a step whose load moves within it (grow_step_in_pieces: the breathing airway's retry and the
// needle's increments). A load under which no step converges (a tip contact whose law is not a number) stands for
// the whole step's load: the first try fails, and the retry in two pieces, the load set before each (none here),
// starts again from where the step began and ends where two plain half steps from there end, bit for bit. A load
// that fails in every split leaves the run failed after the splits asked for, each tried once.
TEST(GrowStepInPieces, AStepThatFailsIsTakenAgainInPiecesFromWhereItBegan) {
  const Tube tube(capped_tube(8e-3));
  Grown g = grow(tube, 30e-3);
  const GrowthState start = g.state;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  TipContact broken;
  broken.axis = Vec3::UnitX();
  broken.law = [nan](double) { return ContactLaw{nan, nan, nan}; };
  const GrowthControl plain{.pressure = 35e3, .tether_length = 40e-3};
  GrowthControl control = plain;
  std::vector<std::pair<int, int>> loads, reached;
  const GrowthStatus r = grow_step_in_pieces(
      g.model, {}, control, g.state, g.ws, 0.05, {1, 2, 4},
      [&](int j, int pieces) {
        loads.emplace_back(j, pieces);
        control.tip_contact = pieces == 1 ? std::optional<TipContact>(broken) : std::nullopt;
      },
      [&](int j, int pieces) { reached.emplace_back(j, pieces); });
  ASSERT_TRUE(r.converged) << r.failure;
  EXPECT_EQ(loads, (std::vector<std::pair<int, int>>{{1, 1}, {1, 2}, {2, 2}}));
  EXPECT_EQ(reached, (std::vector<std::pair<int, int>>{{1, 2}, {2, 2}}));
  GrowthState halves = start;
  GrowthWorkspace ws;
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(grow_step(g.model, {}, plain, halves, ws, 0.025).converged);
  ASSERT_EQ(halves.body.x.size(), g.state.body.x.size());
  for (std::size_t i = 0; i < halves.body.x.size(); ++i) EXPECT_EQ(halves.body.x[i], g.state.body.x[i]) << i;
  EXPECT_EQ(halves.time, g.state.time);

  g.state = start;
  loads.clear();
  control.tip_contact = broken;
  const GrowthStatus fails = grow_step_in_pieces(g.model, {}, control, g.state, g.ws, 0.05, {1, 2},
                                                 [&](int j, int pieces) { loads.emplace_back(j, pieces); });
  EXPECT_FALSE(fails.converged);
  EXPECT_FALSE(fails.failure.empty());
  EXPECT_EQ(loads, (std::vector<std::pair<int, int>>{{1, 1}, {1, 2}}));
  EXPECT_EQ(g.state.body.x.back(), start.body.x.back());  // the last converged state: the step's start
  const auto none = [](int, int) {};
  EXPECT_THROW(grow_step_in_pieces(g.model, {}, plain, g.state, g.ws, 0.05, {}, none), InputError);
  EXPECT_THROW(grow_step_in_pieces(g.model, {}, plain, g.state, g.ws, 0.05, {1, 0}, none), InputError);
}

}  // namespace
}  // namespace magvine::robot
