#pragma once
/// Error-against-runtime study of the airway-graph extraction's resolution knob (the voxel edge of
/// anatomy::extract_airway_graph): the default generated bronchial tree (Weibel A to generation 6) against its
/// ground-truth graph at voxel edges from 1 mm down to 0.27 mm. Writes a CSV for tools/plot_centerline_study.py.

#include <filesystem>

namespace magvine::studies {

/// Writes `dir/centerline_study.csv` with columns
/// voxel_m,seconds,lumen_voxels,branches,reference_branches,same_topology,mean_distance_rel,mean_radius_err,
/// p95_radius_err,p95_radius_err_away (distances and radius errors relative to the reference radius; the last away
/// from junctions and ends), atomically. Progress on stderr.
void run_centerline_study(const std::filesystem::path& dir);

}  // namespace magvine::studies
