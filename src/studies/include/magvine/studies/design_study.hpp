#pragma once
/// The design study (`magvine study design`, issue 29; docs/design.md): thesis appendix A.1.5.1's catheter (40 mm ×
/// Ø4 mm, five sections, |Br| = 0.125 T, NdFeB–silicone, 40 edges) in a fixed uniform 20 mT field, designed by the
/// three methods (least-squares, L-BFGS-B, Bayesian optimisation) for
///  - reachable targets: the forward model's shape (9 points every 5 mm) of random designs (seeds 101…), each from
///    the random start of seed 1…;
///  - the thesis-like arbitrary shapes S (±90° over each half, in the field's plane) and hook (90° in that plane, then
///    90° out of it), from four random starts each.
/// Per design: iterations, evaluations and wall time until the best RMS first reaches 2 mm and 0.5 mm, and at the end.
/// The objective's history (best RMS against iterations and time) and the shapes are written for the plots.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "magvine/design/design.hpp"

namespace magvine::studies {

/// The A.1.5.1 catheter problem with a straight target (replace spec.target).
design::DesignProblem thesis_catheter_problem();

/// Points every L/(points − 1) along a curve of length L from the origin along x, integrated from its curvature
/// vector κ(s) (the bend's direction times its curvature, world frame; its part along the tangent is ignored).
std::vector<Vec3> curve_target(double length, int points, const std::function<Vec3(double)>& curvature);

struct DesignStudyRun {
  std::string target;  ///< "reachable-<seed>", "S" or "hook"
  std::string method;  ///< "least-squares", "lbfgsb", "bayesian"
  std::uint64_t start_seed = 0;
  design::DesignResult result;
  /// The first history step at which the best RMS was at most 2 mm and 0.5 mm (−1: never).
  int iterations_to_2mm = -1;
  int evaluations_to_2mm = -1;
  double seconds_to_2mm = -1.0;
  int iterations_to_half_mm = -1;
  int evaluations_to_half_mm = -1;
  double seconds_to_half_mm = -1.0;
};

/// Runs the study; writes OUT/design_study.csv (one row per design), OUT/design_history.csv (every evaluation's best
/// RMS) and OUT/design_shapes.csv (the S and hook targets and their least-squares designs' points). `reachable`: how
/// many reachable targets. Calls `progress` after each design.
std::vector<DesignStudyRun> run_design_study(const std::filesystem::path& out, int reachable,
                                             const std::function<void(const DesignStudyRun&)>& progress = {});

}  // namespace magvine::studies
