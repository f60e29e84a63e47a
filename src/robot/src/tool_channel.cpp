#include "magvine/robot/tool_channel.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <string>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::robot {

double tool_bending_stiffness(const ChannelTool& tool) {
  return tool.modulus * kPi * (std::pow(tool.outer_diameter, 4) - std::pow(tool.inner_diameter, 4)) / 64.0;
}

void add_channel_tool(RodModel& model, const ChannelTool& tool) {
  if (!(tool.outer_diameter > 0.0 && tool.inner_diameter >= 0.0 && tool.inner_diameter < tool.outer_diameter &&
        std::isfinite(tool.outer_diameter))) {
    throw InputError("channel tool: need 0 <= inner_diameter < outer_diameter");
  }
  if (!(tool.modulus > 0.0 && std::isfinite(tool.modulus))) throw InputError("channel tool: modulus must be > 0");
  const double ei = tool_bending_stiffness(tool);
  if (model.inflated) {
    model.inflated->flat_bending_stiffness += ei;
  } else {
    model.bending_stiffness_2 += ei;
    model.bending_stiffness_3 += ei;
  }
}

namespace {

/// Whether the straight equilibrium under tip force F is a strict minimum (its Hessian positive definite).
bool stable(RodModel& model, double force, const RodConstraints& held) {
  model.tip_force = -force * model.base_frame.col(0);
  RodState state = straight_rod(model);
  const RodSolveReport r = solve_rod_statics(model, {}, state, {}, nullptr, &held);
  if (!r.converged) return false;
  // A buckled state found by the solve (an imperfection from round-off) is past the critical force too.
  for (const Vec3& x : state.x) {
    const Vec3 d = x - model.base_position;
    const Vec3 t = model.base_frame.col(0);
    if ((d - t.dot(d) * t).norm() > 1e-6 * model.length) return false;
  }
  const MatX h = rod_hessian(model, {}, state, 1.0, HessianMethod::analytic, &held);
  return Eigen::LLT<MatX>(h).info() == Eigen::Success;  // Cholesky succeeds exactly when h is positive definite
}

}  // namespace

BucklingResult buckling_tip_force(RodModel model, const std::vector<int>& held_nodes) {
  model.gravity = Vec3::Zero();
  model.tip_moment = Vec3::Zero();
  double ei = std::max(model.bending_stiffness_2, model.bending_stiffness_3);
  if (model.inflated) ei += model.inflated->flat_bending_stiffness;
  if (!(ei > 0.0) || !(model.length > 0.0) || model.edges < 1) {
    throw InputError("buckling_tip_force: the body needs a positive length, edges and bending stiffness");
  }
  const double h = model.length / model.edges;
  RodConstraints held;
  const RodState straight = straight_rod(model);
  for (const int node : held_nodes) {
    if (node < 1 || node > model.edges) {
      throw InputError("buckling_tip_force: held node " + std::to_string(node) + " outside 1.." +
                       std::to_string(model.edges));
    }
    // Stiff against the body: 1e3 times the force that bends one edge by its own length's worth.
    held.anchors.push_back({node, straight.x[static_cast<std::size_t>(node)], model.base_frame.col(0),
                            1e3 * ei / (h * h * h)});
  }
  BucklingResult out;
  // Bracket from the Euler load of the free cantilever, π²EI/(4L²), the lowest of any support.
  double lo = 0.0;
  double hi = kPi * kPi * ei / (4.0 * model.length * model.length);
  for (;;) {
    ++out.solves;
    if (!stable(model, hi, held)) break;
    lo = hi;
    hi *= 2.0;
    if (out.solves > 60) throw InputError("buckling_tip_force: no buckling found below " + std::to_string(hi) + " N");
  }
  while (hi - lo > 1e-4 * hi) {
    const double mid = 0.5 * (lo + hi);
    ++out.solves;
    (stable(model, mid, held) ? lo : hi) = mid;
  }
  out.force = lo;
  return out;
}

}  // namespace magvine::robot
