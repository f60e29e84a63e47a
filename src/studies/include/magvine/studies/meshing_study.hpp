#pragma once
/// Error-against-runtime study of the phantom generator's resolution knob (the meshing grid spacing of
/// anatomy::mesh_implicit): (a) a capsule lumen against its closed-form volume, area and surface (every vertex's
/// exact signed distance), (b) the default bronchial tree against itself at the finest spacing (self-convergence
/// of the volume, the quantity closest to what a robot feels). Writes a CSV for tools/plot_meshing_study.py.

#include <filesystem>

namespace magvine::studies {

/// Writes `dir/meshing_study.csv` with columns
/// case,spacing_m,triangles,seconds,volume_rel_err,area_rel_err,max_surface_err_m
/// (area and surface errors only for the capsule; NaN for the tree), atomically. Progress lines go to stderr.
void run_meshing_study(const std::filesystem::path& dir);

}  // namespace magvine::studies
