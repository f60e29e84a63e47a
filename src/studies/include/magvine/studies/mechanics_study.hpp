#pragma once
/// The robot-mechanics validation studies behind `magvine validate` (issue 4), each written as CSV for
/// tools/plot_mechanics.py:
///  - rod_convergence.csv: the discretised rod against the elastica reference for node counts from coarse to fine
///    (tip error in units of L, time per equilibrium), on the 60 × 3 × 3 mm NdFeB–Dragon Skin beam;
///  - vine_deflection.csv: the thesis's skin MVR (Ø8 mm, 80 mm, h = 65 mm, EPM Ø101.6 mm N52 exact cylinder) in the
///    torque and gradient setups at 1, 6 and 12 kPa against the two-stage reference model (thesis 4.5), bending
///    angle against EPM distance, with where each creases;
///  - fluid_vine.csv: magnetic-fluid vines (Ø4, 5, 7 mm, 50 mm, vertical) at their growing pressure and half of it,
///    bounded and thesis fluid laws, bending angle against EPM distance; fluid_vine_summary.csv: the farthest
///    distance where each bends 20° or more, its largest jump between neighbouring distances (the snap) and its
///    largest angle, next to the thesis's ≈160 mm and 52/59/51°.

#include <filesystem>

namespace magvine::studies {

void run_rod_convergence_study(const std::filesystem::path& dir);

/// One point of the skin-MVR study: the simulator and the two-stage model at EPM distance d [m], pressure [Pa].
struct VineDeflectionPoint {
  double angle_deg = 0.0;            ///< chord angle of the tip from the base direction (thesis: asin(y(l)/l))
  bool creased = false;              ///< some joint carries the collapse moment πR³P
  bool converged = false;
  int iterations = 0;
  double two_stage_angle_deg = 0.0;
  int two_stage_stage = 1;
};
VineDeflectionPoint vine_deflection_point(bool torque_setup, double pressure, double distance, int edges = 40);
void run_vine_deflection_study(const std::filesystem::path& dir);
void run_fluid_vine_study(const std::filesystem::path& dir);

}  // namespace magvine::studies
