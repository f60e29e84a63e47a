#pragma once
/// Reading anatomy meshes (through assimp) and writing STL. Import converts to metres, applies the pose, merges all
/// mesh nodes, welds vertices and removes degenerate and duplicate triangles, so every consumer sees one clean
/// indexed mesh.

#include <filesystem>
#include <string>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {

/// How to read a mesh file.
struct MeshImportOptions {
  LengthUnit units = LengthUnit::kMm;                          ///< unit of the file's coordinates
  double scale = 1.0;                                          ///< extra uniform scale (after the unit)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();      ///< file frame → world, applied after scaling [m]
};

/// Counts from the import, before and after cleaning.
struct MeshImportStats {
  std::size_t raw_vertices = 0;        ///< vertices as stored in the file (STL repeats them per triangle)
  std::size_t raw_triangles = 0;       ///< triangles as read (after triangulating polygons)
  std::size_t degenerate_removed = 0;  ///< zero-area triangles and triangles with a repeated vertex
  std::size_t duplicate_removed = 0;   ///< triangles repeating another's vertex set
  std::size_t meshes_merged = 0;       ///< assimp meshes (all nodes) merged into one
};

/// A cleaned mesh and what happened on the way.
struct ImportedMesh {
  TriangleMesh mesh;                  ///< welded, cleaned, world frame [m]
  MeshImportStats stats;
  std::vector<std::string> warnings;  ///< e.g. implausible size for an airway (units probably wrong)
};

/// Reads any format assimp reads (STL ascii/binary, OBJ, PLY, glTF/GLB, OFF, ...). Throws InputError naming the
/// file for an unreadable, empty or non-finite mesh, and for formats assimp cannot read (legacy VTK), saying which
/// formats work.
ImportedMesh import_mesh(const std::filesystem::path& path, const MeshImportOptions& options = {});

/// Writes a binary STL with coordinates in `units` (mm by default, what 3D Slicer and slicers for 3D printing
/// expect). Atomic: a temporary file renamed into place.
void write_stl(const std::filesystem::path& path, const TriangleMesh& mesh, LengthUnit units = LengthUnit::kMm);

}  // namespace magvine::anatomy
