#pragma once
/// `magvine ct import` and `anatomy: {segmentation: FILE}`: a label map to the three things magvine's anatomy needs —
/// the lumen surface, its mesh report and its airway graph — in memory or as files.

#include <filesystem>
#include <optional>
#include <string>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/ct/segmentation.hpp"

namespace magvine::ct {

struct ImportOptions {
  SurfaceOptions surface;
  anatomy::CenterlineOptions graph;  ///< as `magvine mesh graph` (auto voxel, root at the widest end)
};

/// The imported anatomy. `mesh` is the surface as read back from its STL (float mm, welded), so that it is the mesh
/// `magvine mesh check` and `mesh graph` see in DIR/airway.stl.
struct ImportResult {
  anatomy::ImportedMesh mesh;
  SurfaceReport surface;
  anatomy::MeshReport report;
  anatomy::AirwayGraph graph;
  anatomy::CenterlineReport graph_report;
  /// The trachea's diameters as radiologists measure them (coronal: left–right; sagittal: anterior–posterior;
  /// Breatnach et al., AJR 142, 1984): wall to wall across the root branch in those directions, the median over
  /// the middle half of its centreline [m].
  double trachea_lr = 0.0, trachea_ap = 0.0;
  /// Its area-equivalent diameter 2·sqrt(A/π), A the cross-section's area from 32 rays across the branch, the
  /// median over the same nodes [m].
  double trachea_diameter = 0.0;
  int deepest_generation = 0;
  std::optional<anatomy::CollisionWorld>
      world;  ///< `mesh`'s collision world (the trachea's rays; a scene takes it over)
  double seconds_report = 0.0, seconds_graph = 0.0, seconds_total = 0.0;
};

/// Reads, surfaces, round-trips the surface through STL, analyses it and extracts its graph (nothing written).
ImportResult import_anatomy(const std::filesystem::path& file, const ImportOptions& options = {});

/// The same from a label map already read (`file` names it in messages; surface.seconds_read stays 0).
ImportResult import_anatomy(const LabelVolume& volume, const std::string& file, const ImportOptions& options = {});

/// The same, writing DIR/airway.stl (mm, in the chosen frame), DIR/report.json (`mesh check --json`'s report of it,
/// byte for byte), DIR/graph.json (`mesh graph`'s) and DIR/import.json (options, notes, warnings, components,
/// trachea, timings). All four or none: a failure leaves no file behind.
ImportResult import_to_folder(const std::filesystem::path& file, const std::filesystem::path& dir,
                              const ImportOptions& options = {});

/// import.json's content.
std::string import_json(const std::string& file, const ImportOptions& options, const ImportResult& result);

/// Human-readable summary (a few lines, mm).
std::string import_summary(const std::string& file, const ImportResult& result);

}  // namespace magvine::ct
