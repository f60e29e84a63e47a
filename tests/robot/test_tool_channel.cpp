// The tip force a tool in the channel can push before the body buckles (robot/tool_channel.hpp): Euler's closed
// forms for a clamped rod, free or held at the tip, and the thesis's biopsy scenario (5.6.3) printed against its
// numbers.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/tool_channel.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::robot {
namespace {

constexpr double kLength = 75e-3;
constexpr int kEdges = 75;

// A steel wire rod Ø0.5 mm (G = E/3 in circular_rod; only EI matters here).
RodModel wire() { return circular_rod(kLength, 0.5e-3, 193e9 / 3.0, 7900.0, kEdges); }

TEST(ToolChannel, ClampedFreeRodBucklesAtEulersLoad) {
  // Euler: a column clamped at one end and free at the other buckles at π²EI/(4L²). Tolerance 0.5 %: the chain's
  // discretisation error at 75 edges is ~(π/2N)²/12 ≈ 4e-5 and the near-inextensible shear compliance ~1e-3 ·
  // F/κGA; the bisection stops at 1e-4.
  const RodModel m = wire();
  const double euler = kPi * kPi * m.bending_stiffness_3 / (4.0 * kLength * kLength);
  const BucklingResult r = buckling_tip_force(m, {});
  std::printf("  clamped-free: %.5f N, Euler %.5f N (%d solves)\n", r.force, euler, r.solves);
  EXPECT_NEAR(r.force, euler, 5e-3 * euler);
}

TEST(ToolChannel, TipHeldSidewaysBucklesAtTheClampedPinnedLoad) {
  // Clamped at the base, held sideways at the tip (free to turn): F = β²EI/L² with tan β = β, β = 4.4934.
  // The hold is a stiff spring (1e3 EI/h³), which lowers the load by ~1e-4; same 0.5 %.
  const RodModel m = wire();
  const double beta = 4.493409457909064;
  const double exact = beta * beta * m.bending_stiffness_3 / (kLength * kLength);
  const BucklingResult r = buckling_tip_force(m, {kEdges});
  std::printf("  clamped-pinned: %.5f N, closed form %.5f N\n", r.force, exact);
  EXPECT_NEAR(r.force, exact, 5e-3 * exact);
}

TEST(ToolChannel, AHoldHalfwayRaisesTheLoadToTheShortSpansEuler) {
  // Held sideways at the middle, the free half above the hold buckles like a cantilever on an elastic root; the
  // load lies between the free cantilever of the whole length and that of a clamped half, π²EI/(4(L/2)²). A
  // second check of the hold beside the closed forms above: it must raise the load, and not beyond a clamp.
  const RodModel m = wire();
  const double whole = kPi * kPi * m.bending_stiffness_3 / (4.0 * kLength * kLength);
  const BucklingResult r = buckling_tip_force(m, {kEdges / 2});
  std::printf("  held at the middle: %.4f N (free %.4f N, clamped half %.4f N)\n", r.force, whole, 4.0 * whole);
  EXPECT_GT(r.force, 1.5 * whole);
  EXPECT_LT(r.force, 4.0 * whole);
}

TEST(ToolChannel, ThesisBiopsyForceWithAndWithoutTheRing) {
  // Thesis 5.6.3: Ø5 mm fluid vine grown 75 mm at 35 kPa with a biopsy tool in its channel pushed 1.05 N into a load
  // cell in line with the base before buckling, with a Ø4 mm ring at distance d before the load cell gripping it;
  // much less deflated (no grip). The tool's stiffness is not published: the thin-wire endoscopic tool (Olympus
  // FG-25D) carrying the 20G needle is taken as a Ø0.5 mm steel wire (EI ≈ 6e-4 N·m², an assumption); the buckling
  // load scales with it. The ring is thin: a sideways hold at one node, free to turn (held over 2 mm it acts as a
  // clamp, and at d = 5 mm the 70 mm span behind it buckles first, at ~5 N). The needle's tip slides on the load
  // cell (free sideways).
  VineParameters v = thesis_fluid_vine(kLength, kEdges);
  const ChannelTool tool{.outer_diameter = 0.5e-3, .inner_diameter = 0.0, .modulus = 193e9};
  RodModel inflated = vine_rod(v);
  add_channel_tool(inflated, tool);
  v.pressure = 0.0;
  RodModel deflated = vine_rod(v);
  add_channel_tool(deflated, tool);
  const double without = buckling_tip_force(deflated, {}).force;
  std::printf("  tool EI %.3g N·m², inflated wall EI %.3g N·m²\n", tool_bending_stiffness(tool),
              inflated.bending_stiffness_3);
  std::printf("  deflated, no grip: %.3f N\n", without);
  double nearest = 0.0;
  double previous = 1e9;
  for (const int d : {5, 10, 20, 40}) {
    const int ring = kEdges - d;  // 1 mm edges: node at distance d from the tip
    const double f = buckling_tip_force(inflated, {ring}).force;
    std::printf("  ring %2d mm before the load cell: %.3f N\n", d, f);
    if (d == 5) nearest = f;
    EXPECT_LT(f, previous);  // the thesis: the closer the stabilisation to the tip, the more force
    previous = f;
  }
  std::printf("  thesis: 1.05 N (in line), 1.26 N (corner), much less deflated; simulated %.2f N at d = 5 mm, %.2f N "
              "deflated\n",
              nearest, without);
  // Within the thesis's order of magnitude, and the grip worth several times the deflated vine's force.
  EXPECT_GT(nearest, 1.05 / 10.0);
  EXPECT_LT(nearest, 1.05 * 10.0);
  EXPECT_GT(nearest, 3.0 * without);
}

TEST(ToolChannel, RejectsABadToolOrHold) {
  RodModel m = wire();
  EXPECT_THROW(add_channel_tool(m, {.outer_diameter = 0.5e-3, .inner_diameter = 0.6e-3, .modulus = 1e9}), InputError);
  EXPECT_THROW(add_channel_tool(m, {.outer_diameter = 0.5e-3, .inner_diameter = 0.0, .modulus = 0.0}), InputError);
  EXPECT_THROW(buckling_tip_force(m, {kEdges + 1}), InputError);
}

}  // namespace
}  // namespace magvine::robot
