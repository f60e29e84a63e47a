#pragma once
/// Repairs every imported mesh gets: vertex welding (STL stores each triangle's corners separately), removal of
/// degenerate and duplicate triangles, and removal of vertices no triangle uses.

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// What cleaning changed.
struct CleanStats {
  std::size_t vertices_welded = 0;     ///< vertices merged into another
  std::size_t degenerate_removed = 0;  ///< triangles with a repeated vertex or exactly zero area
  std::size_t duplicate_removed = 0;   ///< triangles with the same three vertices as an earlier one (any order)
  std::size_t unused_removed = 0;      ///< vertices left without a triangle
};

/// Relative weld tolerance: vertices within this fraction of the bounding-box diagonal are merged. STL stores
/// single-precision coordinates (relative resolution 6e-8), so copies of one corner agree far below this, while
/// distinct vertices of any usable anatomy mesh (≥ 1 µm apart on a 0.3 m mesh) stay apart.
inline constexpr double kWeldRelativeTolerance = 1e-9;

/// Welds vertices that fall in the same cell of a grid of pitch `tolerance` [m] (≤ 0 picks
/// kWeldRelativeTolerance × bounding-box diagonal), then removes degenerate and duplicate triangles and unused
/// vertices. Vertex order follows first use, so the result is deterministic.
CleanStats weld_and_clean(TriangleMesh& mesh, double tolerance = 0.0);

/// What keep_largest_component dropped.
struct DroppedParts {
  std::size_t cavities = 0;      ///< closed parts enclosing a negative volume: holes inside the kept one
  std::size_t fragments = 0;     ///< other parts: pieces apart from the kept one
  double cavity_volume = 0.0;    ///< [m³]
  double fragment_volume = 0.0;  ///< [m³], absolute
};

/// Keeps the edge-connected part enclosing the largest |signed volume| (an airway's lumen surface) and removes the
/// others — cavities of a label map's unlabelled voxels inside the lumen, which would be obstacles there, and
/// separate fragments — with the vertices they alone used.
DroppedParts keep_largest_component(TriangleMesh& mesh);

}  // namespace magvine::anatomy
