#pragma once
/// Error-against-runtime study of the CT import's knobs (ct/segmentation.hpp): the level-set voxel, the smoothing
/// passes and the meshing adaptivity, on a label map against a reference surface of the same map (the shared
/// marching-cubes meshes of Med-MPD patients 1 and 5: unsmoothed, so the reference carries the voxel staircase and
/// the error floor is its half-voxel amplitude). Writes a CSV for tools/plot_ct_study.py. CT module only.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace magvine::studies {

/// One label map and its reference surface.
struct CtStudyCase {
  std::string name;                    ///< e.g. "patient1"
  std::filesystem::path segmentation;  ///< NIfTI label map
  std::filesystem::path reference;     ///< reference surface (STL, mm, same world frame)
};

/// One import of the study.
struct CtStudyRun {
  std::string name;
  double voxel_factor = 1.0;  ///< level-set voxel / the map's finest voxel
  int smoothing = 0;
  double adaptivity = 0.0;
  std::size_t triangles = 0;
  bool watertight = false;
  long genus = 0;
  double volume_rel_err = 0.0;    ///< (V − V_ref) / V_ref
  double mean_distance = 0.0;     ///< symmetric mean surface distance [m]
  double rms_distance = 0.0;      ///< [m]
  double max_distance = 0.0;      ///< [m]
  double finest_voxel = 0.0;      ///< the map's finest voxel edge [m]
  double seconds = 0.0;           ///< read + surface (the import's own work, without report and graph)
  double trachea_diameter = 0.0;  ///< the trachea's area-equivalent diameter (ct::ImportResult) [m]
  int deepest_generation = 0;
};

/// Runs every case at every setting of the grid below (voxel factor 1, 1.5, 2 at the default smoothing and
/// adaptivity; smoothing 0, 1, 2, 4, 8 and adaptivity 0, 0.1, 0.3 at the finest voxel) and writes
/// `dir/ct_study.csv` atomically; `progress` sees each run.
void run_ct_study(const std::vector<CtStudyCase>& cases, const std::filesystem::path& dir,
                  const std::function<void(const CtStudyRun&)>& progress);

}  // namespace magvine::studies
