#pragma once
/// Airway graph from any closed airway mesh (issue 8): the centreline tree with branch names, generations and
/// radius profiles, for meshes that bring no graph of their own (CT segmentations exported from 3D Slicer).
///
/// Method (TEASAR: Sato et al., "TEASAR: tree-structure extraction algorithm for accurate and robust skeletons",
/// Pacific Graphics 2000, on a voxelised lumen):
///  1. Voxelise the lumen: rays along x, y and z through every column of cell centres, inside by crossing parity,
///     a cell inside when two of the three agree (one ray grazing an edge cannot flip a cell).
///  2. Exact Euclidean distance transform of the inside (Felzenszwalb & Huttenlocher, Theory of Computing 8, 2012):
///     every inside voxel's distance to the wall (DBF).
///  3. Keep the largest 26-connected component. From the voxel farthest (geodesically) from the widest voxel — an
///     end of the tree — find every voxel's cheapest path with step costs length / DBF² (paths keep to the middle
///     of a lumen of any width: the cost is scale-free).
///  4. Repeatedly take the not-yet-covered voxel farthest along those paths, trace its path back to the skeleton
///     and cover every voxel within ball_scale · max(DBF, the path's median DBF) + ball_margin of the new path (the
///     median lets the balls reach a blind end's corners, where the path's last voxels lie close to the wall). A new terminal path that reaches
///     less than spur_factor × its own radius beyond the wall of the lumen it leaves is a spur of the voxel
///     staircase: covered, not kept. The skeleton is a tree by construction, so branches that touch (handles,
///     genus > 0) do not make loops.
///     Then a leaf's chain shorter than (1 + spur_factor) × the lumen radius at its junction is pruned (it ends
///     inside the junction's own lumen: the corners of a wide flat end such as a capped trachea).
///  5. Root the tree at the widest end (largest radius along its terminal branch: the trachea) unless a root
///     point is given; split it into branches at the bifurcations; smooth each branch; then refine every node on
///     the mesh itself: rays in the plane across the branch find the wall, the node moves to the middle of the
///     cross-section and its radius is the mean distance to it (sub-voxel: the voxel size limits the topology, not
///     the accuracy of positions and radii away from junctions).
/// Names and generations follow add_branch(): children are ordered by their direction's angle about the parent's
/// axis, starting from the parent frame's first normal (deterministic, not anatomical).

#include <array>
#include <cstddef>
#include <optional>
#include <string>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

struct CenterlineOptions {
  double voxel = 0.0;                 ///< voxel edge [m]; 0: auto (about 2 M lumen voxels, within max_cells)
  std::optional<Vec3> root;           ///< a point near the trachea's end [m]; none: the widest end
  double spur_factor = 1.0;           ///< see 4. above
  double ball_scale = 1.5;            ///< see 4. above
  double ball_margin = 2.0;           ///< [voxels]
  std::size_t max_cells = 60'000'000; ///< the voxel grid's cell budget (memory ~5 bytes per cell)
};

/// What the extraction did (for reports and error-against-runtime studies).
struct CenterlineReport {
  double voxel = 0.0;                  ///< [m]
  std::array<int, 3> dims{0, 0, 0};    ///< grid cells
  std::size_t inside_voxels = 0;       ///< in the kept component
  std::size_t components = 0;          ///< 26-connected components of the voxelised lumen
  std::size_t skeleton_voxels = 0;
  int spurs_pruned = 0;
  double seconds = 0.0;                ///< wall-clock time of the whole extraction
};

/// The centreline graph of a closed airway lumen `mesh` [m]. InputError for an unusable mesh (validate_mesh), a
/// voxel so fine that the grid exceeds max_cells, or a lumen with no inside voxel (an open or inside-out mesh).
AirwayGraph extract_airway_graph(const TriangleMesh& mesh, const CenterlineOptions& options = {},
                                 CenterlineReport* report = nullptr);

/// An extracted graph against a reference (ground truth or another method's centrelines).
struct GraphComparison {
  bool same_topology = false;     ///< the rooted trees have the same shape (children unordered)
  std::size_t branches = 0;       ///< in the extracted graph
  std::size_t reference_branches = 0;
  double mean_distance = 0.0;     ///< extracted node to the reference centreline / the reference radius there, mean
  double mean_radius_error = 0.0; ///< |r − r_ref| / r_ref at the nearest reference point, mean over the nodes
  double p95_radius_error = 0.0;  ///< its 95th percentile (junctions: the inscribed circle there is wider)
  /// The 95th percentile over the nodes farther than two reference radii from every reference bifurcation and end
  /// (where a branch's radius is defined without ambiguity).
  double p95_radius_error_away = 0.0;
};

/// The rooted tree's shape with children unordered: "(" + the children's shapes, sorted + ")" per root.
std::string graph_shape(const AirwayGraph& graph);

GraphComparison compare_graphs(const AirwayGraph& extracted, const AirwayGraph& reference);

}  // namespace magvine::anatomy
