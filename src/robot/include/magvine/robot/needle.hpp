#pragma once
/// A biopsy needle pushed out of the tool channel at a grown vine's tip into tissue (issue 31, item 2; thesis 5.6.3
/// and 5.6.5; docs/ct.md, "The needle").
///
/// The needle is a rigid straight tool of `length` and `diameter` whose base sits in the channel at the tip: it
/// leaves along the tip's tangent, and its tip is at x_tip + p·t for a protrusion p. It is pushed out in increments
/// of p, each a quasi-static step of the vine (grow_step with the tether held at the everted length: no growth) in
/// which the tissue's resistance on the needle comes back through the channel as a load on the vine's tip, −F(d)·t,
/// d the depth of the needle tip past the wall along its axis (a ray cast from the tip at the step's start). The
/// depth follows the tip within the step (TipContact, rod.hpp: the needle rides with the tip, so a tip that backs
/// off the tissue is resisted less), so the reaction is part of the step's energy, not a dead load. The body's
/// equilibrium with the walls (barrier, lagged Coulomb friction, clamp) then carries that reaction; its global
/// balance is the check that it does (PunctureStep::imbalance).
///
/// Tissue resistance (needle_tissue_force), after Okamura, Simone & O'Leary (IEEE TBME 51(10), 2004: the insertion
/// force is the capsule's stiffness before it ruptures, then cutting at the tip plus friction along the shaft):
/// F(d) = F_c·d/d_p while the wall deflects (d < d_p, linear where Okamura fits a quadratic), then F_c + f·(d − d_p)
/// once punctured. The thesis designs the vine for ≥ 1 N at the tip (5.6.3: 1.05 and 1.26 N measured); the defaults
/// F_c = 1 N, f = 0 are that design load, not a tissue measurement, and d_p = 2 mm is an assumption (the rise that
/// Okamura's liver needed was several mm).
///
/// The vine holds while its tip slides back (against the needle, along the needle's axis) less than `max_slide`;
/// beyond it, or when the body finds no equilibrium under the load (it collapses: the inflated beam's moment
/// saturates), the puncture stops and the report says the vine did not hold. The biopsy succeeds when the vine holds
/// and the needle's tip ends within the nodule.

#include <functional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/robot/growth.hpp"

namespace magvine::robot {

struct NeedleTool {
  double length = 0.05;          ///< the most it protrudes past the tip [m]
  double diameter = 0.91e-3;     ///< [m]; 20G, the thesis's needle (5.6.3)
  double cutting_force = 1.0;    ///< F_c [N]: at the needle's tip once it has punctured the wall
  double shaft_friction = 0.0;   ///< f [N/m]: along the shaft in tissue
  double puncture_depth = 2e-3;  ///< d_p [m]: how far the wall deflects before it ruptures (F rises to F_c)
  double max_slide = 2e-3;       ///< the vine holds while its tip slides back less than this [m]
  double speed = 5e-3;           ///< insertion speed [m/s] (the steps' time; quasi-static)
  double increment = 0.5e-3;     ///< protrusion per step [m]
};

/// Checks a needle (InputError naming the field otherwise).
void check_needle(const NeedleTool& needle);

/// The tissue's resistance on a needle whose tip is `depth` [m] past the wall [N]: 0 for depth ≤ 0, F_c·depth/d_p up
/// to d_p, F_c + f·(depth − d_p) beyond (Okamura et al. 2004; see the file comment).
double needle_tissue_force(const NeedleTool& needle, double depth);

/// The same law with its potential and stiffness (ContactLaw): Ψ(d) = F_c·d²/(2d_p) up to d_p, then F_c·d_p/2 +
/// F_c·(d − d_p) + f·(d − d_p)²/2; the step's TipContact.
ContactLaw needle_tissue_law(const NeedleTool& needle, double depth);

/// One increment of the puncture.
struct PunctureStep {
  double time = 0.0;               ///< [s]
  double protrusion = 0.0;         ///< p [m]
  double depth = 0.0;              ///< the needle tip past the wall [m] (negative: short of it)
  double force = 0.0;              ///< the tissue's resistance F(depth) = the reaction on the vine's tip [N]
  Vec3 reaction = Vec3::Zero();    ///< R = −F·t on the vine's tip, t the needle's axis then [N]
  Vec3 tip = Vec3::Zero();         ///< the vine's tip [m]
  Vec3 needle_tip = Vec3::Zero();  ///< [m]
  double slide = 0.0;              ///< the vine tip's slide back along the needle's first axis since the start [m]
  /// The change, since before the needle touched tissue, of the walls' and the clamp's forces on the body [N]:
  /// what takes up the reaction. With the reaction R = −F·t, wall + clamp + R is the part of R taken by no support
  /// (the magnetic and gravity loads change a little as the body moves).
  Vec3 wall = Vec3::Zero();
  Vec3 clamp = Vec3::Zero();
  double max_normal = 0.0;    ///< the largest node force on the tissue then [N]
  double total_normal = 0.0;  ///< [N]
  double imbalance = 0.0;     ///< |Σ forces on the body| / |R| (0 when F = 0): the global statics check
  /// |wall + clamp + R| / |R| (0 when F = 0): the share of the reaction that no support takes up (in a field, also
  /// the magnetic load's change as the body moves).
  double unsupported = 0.0;
  /// The largest bending moment along the body over its collapse moment πR³P (inflated_beam.hpp; 0 for a body
  /// without the inflated-beam law): at 1 a joint of the vine creases.
  double moment = 0.0;
};

struct PunctureReport {
  std::vector<PunctureStep> steps;
  Vec3 direction = Vec3::UnitX();  ///< the needle's axis at the start (the tip's tangent), unit
  double wall_distance = -1.0;     ///< from the tip to the wall along it [m]; −1: no wall within the needle's reach
  double target_protrusion = 0.0;  ///< how far it was to be pushed: to the nodule's centre along the axis [m]
  Vec3 needle_tip = Vec3::Zero();  ///< where its tip ended [m]
  double to_nodule = 0.0;          ///< |needle tip − nodule centre| at the end [m]
  /// The needle's tip passed the puncture depth d_p at an equilibrium: the wall ruptured and the reaction reached F_c.
  bool punctured = false;
  bool held = true;                ///< the vine held (slid back less than max_slide, and found its equilibrium)
  double slide = 0.0;              ///< the largest slide back [m]
  double max_force = 0.0;          ///< the largest reaction [N]
  /// The largest reaction at an equilibrium whose slide back was within max_slide: what the vine held [N] (below
  /// max_force when the tip slid back past the limit under the last one).
  double held_force = 0.0;
  double max_imbalance = 0.0;      ///< the largest PunctureStep::imbalance
  double max_unsupported = 0.0;    ///< the largest PunctureStep::unsupported
  /// At the largest reaction: the share of it the walls take up, |wall·R̂|/|R| (the rest: the clamp).
  double wall_share = 0.0;
  double max_normal = 0.0;  ///< the largest node force on the tissue during the puncture [N]
  double max_moment = 0.0;  ///< the largest PunctureStep::moment
  /// Held, and the needle's tip within the nodule (a rupture is not required: a nodule less than d_p past the wall
  /// is reached by the wall's deflection alone).
  bool success = false;
  std::string why;          ///< when it did not succeed
};

/// Pushes `needle` out of the tip of the grown vine in `state` towards a nodule centred at `nodule` with `radius`
/// [m] (see the file comment), at `pressure` [Pa] with the field `field`; advances `state` (its time too). Throws
/// InputError for a bad needle, radius or pressure. `on_step` (optional) sees each converged increment and the state
/// after it (a caller's outputs).
PunctureReport push_needle(const GrowthModel& model, const RodField& field, const NeedleTool& needle,
                           const Vec3& nodule, double radius, double pressure, GrowthState& state,
                           GrowthWorkspace& workspace,
                           const std::function<void(const PunctureStep&, const GrowthState&)>& on_step = {});

}  // namespace magvine::robot
