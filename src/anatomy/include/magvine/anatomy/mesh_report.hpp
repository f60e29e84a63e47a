#pragma once
/// Mesh diagnostics: the numbers `magvine mesh check` prints and writes as JSON, and that the scene loader uses to
/// accept or reject an anatomy mesh.

#include <optional>
#include <string>
#include <vector>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// A boundary loop of an open mesh: a cut airway end.
struct Opening {
  Vec3 centroid = Vec3::Zero();  ///< length-weighted centre of the loop [m]
  Vec3 normal = Vec3::UnitZ();   ///< unit normal of the loop's best-fit plane, pointing out of the mesh interior
  double diameter = 0.0;         ///< equivalent diameter 2·sqrt(A/π) of the loop's projected area [m]
  std::size_t edges = 0;         ///< boundary edges in the loop
};

/// How the triangles are oriented relative to the enclosed lumen.
enum class Orientation {
  kOutward,       ///< consistent, normals point out of the enclosed volume (into tissue)
  kInward,        ///< consistent, normals point into the enclosed volume
  kInconsistent,  ///< neighbouring triangles disagree (a manifold edge used twice in the same direction)
  kUnknown,       ///< consistent but open, so inside/outside is not defined
};

/// Topology and geometry of a cleaned mesh. Counts are after welding and cleaning.
struct MeshReport {
  std::size_t triangles = 0;
  std::size_t vertices = 0;               ///< vertices used by triangles
  Aabb bbox;                              ///< [m]
  double area = 0.0;                      ///< [m²]
  std::optional<double> volume;           ///< enclosed volume [m³], absolute value; nullopt when not closed
  std::size_t boundary_edges = 0;         ///< edges with one triangle
  std::size_t non_manifold_edges = 0;     ///< edges with more than two triangles
  std::size_t components = 0;             ///< edge-connected components
  long genus = 0;                         ///< from the Euler characteristic with boundary loops counted
  bool watertight = false;                ///< no boundary and no non-manifold edges
  Orientation orientation = Orientation::kUnknown;
  std::vector<Opening> openings;          ///< boundary loops, largest first
  std::vector<std::string> warnings;
};

/// Analyses topology (edges, components, genus, openings) and geometry (area, volume, orientation).
MeshReport analyse_mesh(const TriangleMesh& mesh);

/// Name of an orientation for reports ("outward", "inward", "inconsistent", "unknown").
const char* to_string(Orientation orientation);

/// JSON report of `magvine mesh check` (pretty-printed). Contract keys, SI units: triangles, vertices, bbox_min_m,
/// bbox_max_m, area_m2, volume_m3 (null when open), watertight, boundary_edges, non_manifold_edges, components,
/// genus, degenerate_removed, openings [{centroid_m, normal, diameter_m}], warnings; plus raw_triangles,
/// raw_vertices, duplicate_removed, orientation, file, units.
std::string report_json(const std::string& file, const ImportedMesh& imported, const MeshReport& report,
                        LengthUnit units);

/// Human-readable summary (several lines, lengths in mm).
std::string report_summary(const std::string& file, const ImportedMesh& imported, const MeshReport& report);

}  // namespace magvine::anatomy
