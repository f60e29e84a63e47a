#pragma once
/// A tool in the vine's channel and the tip force it can push before the body buckles (thesis 5.6.3, PHYSICS.md §3:
/// a biopsy needle through a Ø5 mm fluid vine grown 75 mm at 35 kPa pushed 1.05 N into a load cell in line with the
/// base and 1.26 N round a corner, with a Ø4 mm ring stabilising it; much less with the vine deflated).
///
/// The tool bends with the body, so its flexural rigidity adds to the wall's (for a vine, to the linear term the
/// inflated-beam law keeps at any pressure, InflatedBending::flat_bending_stiffness). The tip force is a dead load
/// along the base's tangent, against the tip; the body is straight under it until the straight equilibrium stops
/// being a minimum of the energy: the force at which the Hessian there stops being positive definite (bisection on
/// whether its Cholesky factorisation succeeds). A ring or a wall holding the body sideways is a stiff spring on the nodes
/// it touches (NodeAnchor with the tangent as its "normal": sideways held, sliding along the axis free). An inflated
/// vine squeezed into a ring narrower than itself is gripped there; a deflated one is not: that is the "wall
/// stabilisation" of the thesis.

#include <vector>

#include "magvine/robot/rod.hpp"

namespace magvine::robot {

/// A round tool (tube or wire) in the channel.
struct ChannelTool {
  double outer_diameter = 0.0;  ///< [m]
  double inner_diameter = 0.0;  ///< [m]; 0 for a wire
  double modulus = 0.0;         ///< Young's modulus [Pa]
};

/// E·π(D⁴ − d⁴)/64 [N·m²].
double tool_bending_stiffness(const ChannelTool& tool);

/// Adds the tool's bending stiffness to the body (both bending axes; for a vine, to its linear term). Throws
/// InputError for non-positive sizes or modulus.
void add_channel_tool(RodModel& model, const ChannelTool& tool);

struct BucklingResult {
  double force = 0.0;  ///< the largest stable axial tip force [N]
  int solves = 0;      ///< equilibria computed in the bisection
};

/// The axial compressive tip force at which the straight body buckles: `held_nodes` are held sideways (a ring, a
/// load cell's grip); gravity and the field are left out (a bench rig on a table). Bisection to a relative 1e-4.
/// Throws InputError for an invalid model or a held node out of range.
BucklingResult buckling_tip_force(RodModel model, const std::vector<int>& held_nodes);

}  // namespace magvine::robot
