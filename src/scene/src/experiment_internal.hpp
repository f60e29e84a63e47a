#pragma once
// Pieces of the experiment module shared by its parser, navigator, run loop, outputs and trials. Private to the scene
// module.

#include <optional>
#include <string>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/scene/experiment.hpp"

namespace magvine::scene::detail {

/// The magnet body of source i for the placement checks: a cylinder's radius and half length [m]; none for a dipole
/// or a uniform field (points and fields do not collide).
struct MagnetBody {
  double radius = 0.0;
  double half_length = 0.0;
};
std::optional<MagnetBody> magnet_body(const magnetics::FieldModel& magnets, std::size_t i);

/// The least gap between a magnet and the airway wall [m].
inline constexpr double kMagnetClearance = 2e-3;

/// How many of the mesh's vertices lie inside the magnet's cylinder grown by kMagnetClearance (centre, unit axis), and
/// the deepest one's depth [m] (the mesh's edges are far shorter than a magnet, so its vertices stand for it).
std::size_t vertices_inside(const anatomy::TriangleMesh& mesh, const MagnetBody& body, const Vec3& centre,
                            const Vec3& axis, double* depth = nullptr);

/// Why source i of `magnets` may not sit at (centre, axis) (it overlaps the anatomy), or empty.
std::string overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets, std::size_t i,
                            const Vec3& centre, const Vec3& axis);

/// overlap_problem along the move from keyframe a to b (as magnetics::interpolate moves it), sampled every 2 mm and
/// 2°, the end b included; the problem names where on the way.
std::string path_overlap_problem(const anatomy::TriangleMesh& mesh, const magnetics::FieldModel& magnets,
                                 std::size_t i, const MagnetKeyframe& a, const MagnetKeyframe& b);

/// Aims the scene's navigator at `branch` of its graph: the plan's last branch, and its end (within 1.5 lumen radii)
/// the target.
void aim_at(ExperimentScene& scene, int branch);

/// The whole-run figures of metrics.json, also the trials' outcomes.
struct RunFigures {
  double everted_length = 0.0;       ///< at the end [m]
  std::optional<double> final_error;  ///< tip to target at the end [m]; none without a target
  double path = 0.0;                 ///< tip path length [m]
  double max_normal = 0.0;           ///< largest wall normal force on a node [N]
  double max_line_load = 0.0;        ///< largest normal force per length of body [N/m]
  double mean_normal = 0.0;          ///< time average of the total [N]
  double max_shear = 0.0;            ///< largest total shear [N]
  double max_pressure = 0.0;         ///< largest contact pressure on a node [Pa]
  /// A vine's largest contact pressure over its inflation pressure at that step (none for a pushed catheter or rod):
  /// a film presses a flat patch at its own pressure, so far above 1 the contact's rigid sphere carries the load.
  std::optional<double> film_overload;
  std::vector<std::string> branches; ///< graph branches the tip passed through, in order
  int generation = -1;               ///< the deepest generation among them (−1 without a graph)
  std::optional<double> centreline;       ///< tip to the nearest centreline at the end [m] (with a graph)
  std::optional<double> mean_centreline;  ///< its time average [m]
  std::optional<double> progress;    ///< how far along the navigator's planned path the tip got, 0–1
};
RunFigures figures_of(const ExperimentScene& scene, const ExperimentResult& result);

/// Why a run did not reach its target, in one line: a failed step (the run ended there), else the last event that
/// stopped the tip (stall, blocked, squeeze, burst, solver), or that the time ran out while it was still moving;
/// then where the tip was.
std::string failure_reason(const ExperimentResult& result, const RunFigures& figures);

}  // namespace magvine::scene::detail
