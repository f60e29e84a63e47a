#pragma once
/// CT import (optional module, MAGVINE_WITH_CT): from an airway segmentation — a NIfTI label map as 3D Slicer, ITK
/// and the Med-MPD/LIDC data write it — to the closed, smoothed lumen surface the rest of magvine works on.
///
/// Pipeline (docs/ct.md):
///  1. read the label map with libnifti2 (.nii / .nii.gz; voxel → world through the qform, else the sform, else the
///     voxel sizes alone, with a note); NIfTI's world frame is RAS;
///  2. keep the voxels with the label, split them into 6-connected components and keep the largest (a warning names
///     the others);
///  3. OpenVDB: the iso-surface half way between inside and outside voxels of the (possibly anisotropic or oblique)
///     grid, rebuilt as a narrow-band signed distance on an isotropic, world-aligned grid (levelSetRebuild);
///  4. smoothed by Gaussian filtering of the signed distance (LevelSetFilter), which removes the voxel staircase but
///     leaves the distance linear across the surface, so tubes keep their radius to second order;
///  5. meshed at the zero level (volumeToMesh, adaptive: flat stretches get larger triangles), quads split along
///     their shorter diagonal, oriented outward, welded.
/// The result is a closed surface in the file's world frame (RAS, or LPS on request), in metres.

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/eigen_types.hpp"

namespace magvine::ct {

/// World frame of the output. NIfTI's is RAS (+x right, +y anterior, +z superior); DICOM and 3D Slicer's patient
/// frame is LPS (+x left, +y posterior): the same points turned 180° about z.
enum class Frame { kRas, kLps };

/// A label map as read: int32 labels, x fastest, and the voxel-index → world (RAS) map.
struct LabelVolume {
  std::array<int, 3> dims{0, 0, 0};                              ///< voxels along i, j, k
  Eigen::Affine3d index_to_world = Eigen::Affine3d::Identity();  ///< voxel (i, j, k) centre → RAS world [m]
  std::string frame_source;                                      ///< "qform", "sform" or "pixdim" (no orientation)
  std::vector<std::int32_t> labels;                              ///< dims[0]·dims[1]·dims[2] labels, i fastest
  std::array<double, 3> spacing() const;                         ///< voxel edge along i, j, k [m]
};

/// Reads a NIfTI-1 or NIfTI-2 label map (.nii or .nii.gz). Throws InputError naming the file for a file that is not
/// NIfTI, a 4-D image, a non-integer data type with fractional values, or a singular voxel → world map.
LabelVolume read_nifti_labels(const std::filesystem::path& path);

/// How to turn a label map into a surface.
struct SurfaceOptions {
  int label = 1;  ///< which label is the airway lumen
  Frame frame = Frame::kRas;
  double voxel = 0.0;       ///< level-set voxel [m]; 0 = the label map's finest spacing
  int smoothing = 2;        ///< Gaussian passes over the signed distance (0 = the voxel surface, unsmoothed)
  double adaptivity = 0.1;  ///< OpenVDB's meshing adaptivity in [0, 1]: 0 = uniform triangles, 1 = fewest
};

/// What the surface came from and what the import did on the way.
struct SurfaceReport {
  std::array<int, 3> dims{0, 0, 0};
  std::array<double, 3> spacing{0, 0, 0};  ///< label map voxel [m]
  std::string frame_source;                ///< see LabelVolume
  double obliquity_deg = 0.0;              ///< largest angle between a grid axis and its world axis [°]
  double voxel = 0.0;                      ///< level-set voxel used [m]
  std::size_t label_voxels = 0;            ///< voxels with the label
  std::vector<std::size_t> components;     ///< 6-connected components' voxel counts, largest first (first kept)
  std::vector<std::string> notes;          ///< anisotropic or oblique grid, no orientation: what was done
  std::vector<std::string> warnings;       ///< several components: which were dropped
  double seconds_read = 0.0, seconds_surface = 0.0;
};

/// The lumen surface of one label: closed, oriented outward (normals into tissue), in `options.frame` [m].
/// Throws InputError naming the file when no voxel carries the label (the labels present are listed).
anatomy::TriangleMesh segmentation_surface(const LabelVolume& volume, const SurfaceOptions& options,
                                           const std::string& file, SurfaceReport* report = nullptr);

/// Both steps: read the file, then surface it (report.seconds_read is the read, seconds_surface the rest).
anatomy::TriangleMesh import_segmentation(const std::filesystem::path& path, const SurfaceOptions& options,
                                          SurfaceReport* report = nullptr);

}  // namespace magvine::ct
