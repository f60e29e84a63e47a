#pragma once
/// Reference solver, kept apart from the simulator's discretised rod: the planar magnetic elastica, a clamped
/// cantilever in the x–y plane under distributed magnetic torque and force, gravity and tip loads, solved as a
/// boundary-value problem by shooting (PHYSICS.md §7; Wang et al. 2020; thesis chapter 3):
///
///   x' = cos θ,  y' = sin θ,  EI θ' = m,
///   n' = −f(s),  m' = −(t × n)_z − τ(s),          t = (cos θ, sin θ),
///   x(0) = y(0) = 0, θ(0) = θ0 (clamp),   n(L) = F_tip, m(L) = M_tip (free end),
///
/// with n the internal force and m the bending moment carried across a section (from the tip side onto the base
/// side), and per unit length
///   τ = A (M × B)_z,  f = A Gᵀ M + ρ A g,  M = (Br/μ0) d,
/// d the magnetisation direction, fixed in the body: the tangent (axial) or the in-plane normal (ẑ × t), B and
/// G = ∂B/∂x the field and its gradient at the centreline point (z = 0).
///
/// The unknown base reactions (n(0), m(0)) are found by Newton's method on the tip residual, with the loads ramped
/// from zero (continuation, the step halved when Newton fails) so that large deflections follow the branch that
/// grows from the straight beam. The ODE is integrated by classical RK4 on a uniform grid (error O(h⁴)).

#include <functional>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"
#include "magvine/magnetics/field_function.hpp"

namespace magvine::robot {

/// Direction of the remanent magnetisation in the body frame of a planar beam.
enum class PlanarMagnetisation {
  kAxial,   ///< along the tangent t
  kNormal,  ///< along ẑ × t (the base normal +y for a beam clamped along +x)
};

/// One planar cantilever problem, SI units.
struct ElasticaProblem {
  double length = 0.0;             ///< L [m], > 0
  double bending_stiffness = 0.0;  ///< EI [N·m²], > 0
  double area = 0.0;               ///< cross-section A [m²] (magnetic volume and mass per length), ≥ 0
  double density = 0.0;            ///< ρ [kg/m³], ≥ 0
  double base_angle = 0.0;         ///< θ0, tangent at the clamp from +x [rad]
  Eigen::Vector2d gravity = Eigen::Vector2d::Zero();  ///< g [m/s²]
  double remanence = 0.0;                             ///< Br [T]
  PlanarMagnetisation magnetisation = PlanarMagnetisation::kAxial;
  magnetics::FieldFunction field;                                ///< empty: no field; only the x–y parts are used
  Eigen::Vector2d tip_force = Eigen::Vector2d::Zero();  ///< F_tip [N]
  double tip_moment = 0.0;                              ///< M_tip about +z [N·m]
};

struct ElasticaOptions {
  int intervals = 1000;       ///< RK4 steps along the length
  double tolerance = 1e-12;   ///< on the tip residual, relative to EI/L² (forces) and EI/L (moment)
  int max_newton = 50;        ///< per load step
  int min_load_steps = 8;     ///< the load ramp starts with steps of 1/min_load_steps
  int max_load_steps = 4096;  ///< gives up (converged = false) when the ramp would need more
  /// A load step is accepted only if the tip angle changes by at most this [rad]: near a bifurcation or a snap the
  /// path turns quickly, and a long step can land Newton on another (unstable) branch.
  double max_angle_step = 0.1;
};

/// Centreline samples at s_k = k·L/intervals, k = 0..intervals.
struct ElasticaSolution {
  std::vector<double> s;                                 ///< arc length [m]
  std::vector<Eigen::Vector2d> position;                 ///< [m]
  std::vector<double> angle;                             ///< tangent angle θ [rad]
  std::vector<double> moment;                            ///< bending moment m = EI θ' [N·m]
  Eigen::Vector2d base_force = Eigen::Vector2d::Zero();  ///< n(0) [N]
  double base_moment = 0.0;                              ///< m(0) [N·m]
  bool converged = false;
  int newton_iterations = 0;  ///< summed over the load ramp
  int load_steps = 0;

  const Eigen::Vector2d& tip() const { return position.back(); }
  double tip_angle() const { return angle.back(); }
};

/// Solves the problem; throws InputError for non-positive length or stiffness, negative area or density, or
/// intervals < 1. Returns converged = false (with the last accepted state) when the continuation fails.
ElasticaSolution solve_elastica(const ElasticaProblem& problem, const ElasticaOptions& options = {});

}  // namespace magvine::robot
