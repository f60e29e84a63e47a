#pragma once
/// Error against runtime of vine growth in anatomy (issue 28): the thesis's Ø5 mm magnetic-fluid vine (35 kPa,
/// yield 20 kPa, no field) grown from about 5 to 105 mm in the two bench_growth cases: `carina`, from 70 mm down the trachea of the
/// generated bronchial tree (Weibel A to generation 4, 0.5 mm meshing), leaning on its wall under gravity, past the
/// carina into a main bronchus; `y`, in the Y bifurcation phantom from against one side wall into that side's
/// daughter (turning 35° at the junction). Per case three sweeps, each changing one resolution knob from the defaults (edge length h = R,
/// dt = 20 ms, d̂ = 2 % of R) and compared with its own finest setting:
///  - the tip path: the largest distance between the tips at equal everted lengths (every 5 mm from 10 to 105 mm) [m];
///  - the peak wall normal force on a node and the peak total wall normal force over the run (relative errors).
/// A node's force is a share of a distributed load (about the load per length times h), so it changes with h where
/// the total does not; both are written.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/core/eigen_types.hpp"

namespace magvine::studies {

enum class GrowthStudyCase { kCarina, kY };

/// One growth run of the study.
struct GrowthStudyRun {
  GrowthStudyCase which = GrowthStudyCase::kCarina;
  std::string knob;              ///< "edge_length", "dt" or "contact_distance"
  double value = 0.0;            ///< the knob's value [m] or [s]
  bool ok = false;               ///< grew the 100 mm without a failed step
  double grown = 0.0;            ///< [m]
  double peak_node_normal = 0.0;   ///< [N]
  double peak_total_normal = 0.0;  ///< [N]
  std::vector<Vec3> tips;        ///< the tip at everted lengths of 10, 15, …, 105 mm
  int steps = 0;
  int newton = 0;
  double seconds = 0.0;          ///< wall time of the run (one thread)
  std::string failure;
};

/// The case's anatomy, built once: the generated tree to generation 4 at 0.5 mm meshing (kCarina), the Y
/// bifurcation phantom (kY). bench_growth grows in the same worlds.
const anatomy::CollisionWorld& growth_study_world(GrowthStudyCase which);

/// One run with the given knobs (h [m], dt [s], d̂ [m]; 0: the default).
GrowthStudyRun run_growth_study_case(GrowthStudyCase which, double edge_length, double dt, double contact_distance);

/// Writes `dir/growth_study.csv` (one row per run: case, knob, value, runtime, errors against that sweep's finest run)
/// atomically, for tools/plot_growth_study.py. `quick`: two settings per knob (for tests).
void run_growth_study(const std::filesystem::path& dir, bool quick,
                      const std::function<void(const GrowthStudyRun&)>& progress = {});

}  // namespace magvine::studies
