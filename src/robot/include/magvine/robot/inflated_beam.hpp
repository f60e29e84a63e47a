#pragma once
/// The inflated-beam law of a thin-walled pressurised tube (Comer & Levy 1963, as used in thesis 4.5, eq 4.6–4.13;
/// PHYSICS.md §3), and the thesis's two-stage vine bending model built on it, kept as a reference solver apart from
/// the simulator's discretised vine.
///
/// A tube of radius R at internal pressure P with wall flexural rigidity EI bends linearly, κ = M/EI, until the
/// moment reaches the wrinkling moment M_w = πR³P/2. Above it the compressed side wrinkles over a half-angle φ0:
///   M/(PR³) = π(2π − 2φ0 + sin 2φ0) / (4[sin φ0 + (π − φ0) cos φ0]),          (eq 4.8)
///   κ = (M/EI)·2π/(2π − 2φ0 + sin 2φ0),                                          (eq 4.6)
/// and at φ0 → π the section collapses at M_c = πR³P: a crease forms. A crease of angle θ resists with
///   M = πR³P(1 + tan²(θ/2)).                                                     (eq 4.13)
///
/// Two-stage model (thesis 4.5): the loads act on the straight body, M_e(x) = ∫_x^l [q_f(u)(u − x) + q_τ(u) −
/// q_g(u)] du (PHYSICS.md's lever arm u − x; the thesis prints l − u, equal only for uniform q_f). Stage 1 integrates
/// the curvature of eq 4.6 from the clamp, θ = asin(y(l)/l). Stage 2, when M_e(0) reaches M_c (or stage 1 gives
/// y(l) > l): a crease at the base with the body straight beyond it, at the angle θ where the base moment of the
/// loads on the body turned by θ equals the crease moment (eq 4.12).

#include <functional>

namespace magvine::robot {

/// Wrinkling moment M_w = πR³P/2 [N·m] (R [m], P [Pa]).
double wrinkling_moment(double radius, double pressure);
/// Collapse moment M_c = πR³P [N·m].
double collapse_moment(double radius, double pressure);
/// Moment at wrinkle half-angle φ0 ∈ [0, π] (eq 4.8) [N·m]; M_w at 0, M_c at π (the limit).
double wrinkled_moment(double wrinkle_angle, double radius, double pressure);
/// Inverse of wrinkled_moment on [M_w, M_c]: 0 below M_w, π at or above M_c [rad].
double wrinkle_angle(double moment, double radius, double pressure);
/// Curvature of the inflated beam under bending moment |M| (eq 4.6) [1/m]; +∞ at or above M_c. Sign of M kept.
double inflated_curvature(double moment, double radius, double pressure, double bending_stiffness);
/// Resisting moment of a crease of angle θ ∈ [0, π) (eq 4.13) [N·m].
double crease_moment(double crease_angle, double radius, double pressure);

/// The moment–curvature law of eq 4.6/4.8 in normalised form, k = κ·EI/(πR³P) and m = M/(πR³P), which is the same
/// for every tube: m = k up to k = ½ (wrinkling), then, with ε = π − φ0, D = sin ε − ε cos ε and N = 2ε − sin 2ε,
///   k = π/(2D),   m = N/(4D)   (m → 1, the collapse, as k → ∞),
/// and the stored energy per unit length in units of (πR³P)²/EI, Φ(k) = ∫₀ᵏ m dk', in closed form (integration by
/// parts with ∫ sin²ε/D² dε = −cos ε/D):
///   Φ = k²/2 (k ≤ ½),   Φ = ¼ + (π/16)(N/D² + 4 cos ε/D) (k > ½).
struct NormalisedBending {
  double moment = 0.0;  ///< m(k)
  double energy = 0.0;  ///< Φ(k)
  double stiffness = 0.0;  ///< dm/dk: 1 up to k = ½, then (Nε − 4D sin ε)/(2πε), falling to 0 at the collapse
};
/// The law at normalised curvature k ≥ 0.
NormalisedBending normalised_inflated_bending(double curvature);

/// Distributed loads of the two-stage model, per unit length along the straight body from the clamp (x ∈ [0, l]).
struct TwoStageLoads {
  std::function<double(double)> force = {};   ///< q_f, transverse force [N/m] (empty: none)
  std::function<double(double)> torque = {};  ///< q_τ, bending torque [N·m/m] (empty: none)
  std::function<double(double)> gravity_moment =
      {};  ///< q_g, moment of gravity opposing the bend [N·m/m] (empty: none)
  /// Stage 2: M_e(0) of the loads on the straight body turned by the crease angle θ [N·m]. Empty: the stage-1
  /// base moment for every θ.
  std::function<double(double)> creased_base_moment = {};
};

struct TwoStageVine {
  double radius = 0.0;             ///< R [m]
  double pressure = 0.0;           ///< P [Pa]
  double bending_stiffness = 0.0;  ///< EI of the wall (and skin) [N·m²]
  double length = 0.0;             ///< l [m]
};

struct TwoStageResult {
  int stage = 1;                 ///< 1: bending and wrinkling; 2: creased at the base
  double angle = 0.0;            ///< bending angle θ [rad]
  double tip_deflection = 0.0;   ///< y(l) [m] (stage 2: l·sin θ)
  double wrinkled_length = 0.0;  ///< x_w: length from the clamp over which the wall is wrinkled [m]
  double base_moment = 0.0;      ///< M_e(0) of stage 1 [N·m]
};

/// Solves the two-stage model (trapezoids with `intervals` steps for stage 1). Throws InputError for
/// non-positive radius, pressure, stiffness or length.
TwoStageResult solve_two_stage(const TwoStageVine& vine, const TwoStageLoads& loads, int intervals = 2000);

}  // namespace magvine::robot
