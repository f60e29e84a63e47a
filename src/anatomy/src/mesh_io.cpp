#include "magvine/anatomy/mesh_io.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

#include "magvine/anatomy/mesh_clean.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"

namespace magvine::anatomy {
namespace {

// Size range of a plausible airway mesh (its largest bounding-box extent). A trachea alone is ~100 mm long and a
// whole bronchial tree ~250 mm tall; bench phantoms are a few centimetres. Outside this range the declared unit
// is most likely wrong (a mm file read as m is 1000× too large).
constexpr double kPlausibleMinExtent = 5e-3;  // [m]
constexpr double kPlausibleMaxExtent = 1.0;   // [m]

constexpr const char* kReadableFormats =
    "STL (ascii/binary), OBJ, PLY, glTF/GLB, OFF, 3MF, COLLADA, FBX and the other formats assimp reads";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string unit_name(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::kMm: return "mm";
    case LengthUnit::kCm: return "cm";
    case LengthUnit::kM: return "m";
  }
  return "m";
}

// Checks that make a file unreadable before assimp sees it, with messages a user can act on.
void check_readable(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(file, 0, "mesh", "file not found");
  if (std::filesystem::is_directory(path, ec)) throw InputError(file, 0, "mesh", "is a directory, not a mesh file");
  if (std::filesystem::file_size(path, ec) == 0 || ec) throw InputError(file, 0, "mesh", "file is empty");

  // Legacy VTK (3D Slicer's .vtk model export) is the common format assimp cannot read: say what to do instead.
  std::ifstream in(path, std::ios::binary);
  std::array<char, 24> head{};
  in.read(head.data(), head.size());
  const bool vtk_header = std::strncmp(head.data(), "# vtk DataFile", 14) == 0;
  if (vtk_header || lower(path.extension().string()) == ".vtk") {
    throw InputError(file, 0, "mesh",
                     std::string("legacy VTK is not readable (assimp has no VTK importer); export the model from "
                                 "3D Slicer as STL, OBJ or PLY instead. Readable: ") +
                         kReadableFormats);
  }
  Assimp::Importer probe;
  const std::string ext = path.extension().string();
  if (ext.empty() || !probe.IsExtensionSupported(ext)) {
    throw InputError(file, 0, "mesh",
                     "unsupported file extension '" + ext + "'; readable: " + kReadableFormats);
  }
}

aiMatrix4x4 accumulated(const aiNode* node) {
  aiMatrix4x4 m = node->mTransformation;
  for (const aiNode* p = node->mParent; p != nullptr; p = p->mParent) m = p->mTransformation * m;
  return m;
}

// Appends every triangle of every mesh instance in the node tree, with the node transforms applied; counts the
// faces that are not triangles (points, polylines) in `skipped`.
void collect(const aiScene& scene, const aiNode& node, const Eigen::Affine3d& to_world, TriangleMesh& out,
             std::size_t& instances, std::size_t& skipped) {
  const aiMatrix4x4 m = accumulated(&node);
  Eigen::Matrix4d node_matrix;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) node_matrix(r, c) = static_cast<double>(m[static_cast<unsigned>(r)][static_cast<unsigned>(c)]);
  }
  const Eigen::Affine3d transform = to_world * Eigen::Affine3d(node_matrix);
  for (unsigned k = 0; k < node.mNumMeshes; ++k) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[k]];
    ++instances;
    const auto base = static_cast<std::uint32_t>(out.vertices.size());
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D& p = mesh.mVertices[v];
      out.vertices.push_back(transform * Vec3(p.x, p.y, p.z));
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) {  // points and lines carry no surface
        ++skipped;
        continue;
      }
      out.triangles.push_back({base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) collect(scene, *node.mChildren[c], to_world, out, instances, skipped);
}

// Binary STL, read directly: an 80-byte header, a uint32 triangle count, then 50 bytes per triangle (normal and
// three corners as little-endian float32, a uint16 attribute). The layout is fixed, so a file is binary STL exactly
// when its size is 84 + 50·count; assimp handles everything else (ASCII STL, truncated files: its error). Reading
// it here skips assimp's per-face allocations (0.3 s of a 1 M-triangle import), for the common CT export.
bool read_binary_stl(const std::filesystem::path& path, const Eigen::Affine3d& to_world, TriangleMesh& out) {
  if (lower(path.extension().string()) != ".stl") return false;
  std::ifstream in(path, std::ios::binary);
  std::array<char, 84> head{};
  if (!in.read(head.data(), head.size())) return false;
  std::uint32_t count = 0;
  std::memcpy(&count, head.data() + 80, sizeof count);
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec || count == 0 || size != 84 + 50 * static_cast<std::uintmax_t>(count)) return false;
  std::vector<char> bytes(50 * static_cast<std::size_t>(count));
  if (!in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()))) return false;
  out.vertices.resize(3 * static_cast<std::size_t>(count));
  out.triangles.resize(count);
  std::array<float, 9> corners{};
  for (std::uint32_t t = 0; t < count; ++t) {
    std::memcpy(corners.data(), bytes.data() + 50 * static_cast<std::size_t>(t) + 12, sizeof corners);
    for (std::uint32_t c = 0; c < 3; ++c) {
      out.vertices[3 * t + c] = to_world * Vec3(corners[3 * c], corners[3 * c + 1], corners[3 * c + 2]);
    }
    out.triangles[t] = {3 * t, 3 * t + 1, 3 * t + 2};
  }
  return true;
}

std::string format_length(double metres) {
  std::ostringstream s;
  s.precision(3);
  if (metres >= 1.0) {
    s << metres << " m";
  } else {
    s << metres * 1e3 << " mm";
  }
  return s.str();
}

}  // namespace

ImportedMesh import_mesh(const std::filesystem::path& path, const MeshImportOptions& options) {
  const std::string file = path.string();
  if (!(options.scale > 0.0) || !std::isfinite(options.scale)) {
    throw InputError(file, 0, "scale", "must be a finite number > 0");
  }
  check_readable(path);

  ImportedMesh result;
  const Eigen::Affine3d to_world =
      Eigen::Affine3d(options.pose) * Eigen::Scaling(metres_per(options.units) * options.scale);
  std::size_t skipped = 0;
  if (read_binary_stl(path, to_world, result.mesh)) {
    result.stats.meshes_merged = 1;
  } else {
    Assimp::Importer importer;
    // Triangulate polygons (OBJ/PLY quads); welding and cleaning are done here, faster and with reported counts.
    const aiScene* scene = importer.ReadFile(file, aiProcess_Triangulate);
    if (scene == nullptr || scene->mRootNode == nullptr) {
      std::string why = importer.GetErrorString();
      std::replace(why.begin(), why.end(), '\n', ' ');
      throw InputError(file, 0, "mesh", "cannot read: " + (why.empty() ? std::string("unknown assimp error") : why));
    }
    std::size_t vertex_count = 0;
    std::size_t face_count = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
      vertex_count += scene->mMeshes[m]->mNumVertices;
      face_count += scene->mMeshes[m]->mNumFaces;
    }
    result.mesh.vertices.reserve(vertex_count);  // exact unless a mesh is instanced by several nodes
    result.mesh.triangles.reserve(face_count);
    collect(*scene, *scene->mRootNode, to_world, result.mesh, result.stats.meshes_merged, skipped);
  }
  result.stats.raw_vertices = result.mesh.vertices.size();
  result.stats.raw_triangles = result.mesh.triangles.size();
  if (result.mesh.triangles.empty()) {
    throw InputError(file, 0, "mesh",
                     skipped > 0 ? "contains no triangles, only " + std::to_string(skipped) +
                                       " points/polylines (a centerline file?)"
                                 : std::string("contains no triangles"));
  }
  for (std::size_t v = 0; v < result.mesh.vertices.size(); ++v) {
    if (!result.mesh.vertices[v].allFinite()) {
      throw InputError(file, 0, "vertex " + std::to_string(v), "non-finite coordinate (NaN or infinity)");
    }
  }

  const CleanStats clean = weld_and_clean(result.mesh);
  result.stats.degenerate_removed = clean.degenerate_removed;
  result.stats.duplicate_removed = clean.duplicate_removed;
  if (result.mesh.triangles.empty() || !(surface_area(result.mesh) > 0.0)) {
    throw InputError(file, 0, "mesh", "has zero area (every triangle is degenerate)");
  }

  const Aabb box = bounding_box(result.mesh);
  const double extent = (box.max - box.min).maxCoeff();
  if (extent > kPlausibleMaxExtent || extent < kPlausibleMinExtent) {
    result.warnings.push_back("mesh is " + format_length(extent) + " across with units '" + unit_name(options.units) +
                              "': implausible for an airway (expected 5 mm to 1 m); check --units");
  }
  return result;
}

void write_stl(const std::filesystem::path& path, const TriangleMesh& mesh, LengthUnit units) {
  // Binary STL: 80-byte header, uint32 count, then per triangle 12 little-endian floats (normal, 3 corners) and a
  // uint16 attribute. x86 and ARM Linux are little-endian, which the format requires.
  const double scale = 1.0 / metres_per(units);
  AtomicFile out(path);
  std::array<char, 80> header{};
  const std::string title = "magvine binary STL, units " + unit_name(units);
  std::memcpy(header.data(), title.data(), std::min(title.size(), header.size()));
  out.stream().write(header.data(), header.size());
  const auto count = static_cast<std::uint32_t>(mesh.triangles.size());
  out.stream().write(reinterpret_cast<const char*>(&count), sizeof count);
  std::array<float, 12> record{};
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Vec3 n = area_vector(mesh, t).normalized();
    for (int k = 0; k < 3; ++k) record[static_cast<std::size_t>(k)] = static_cast<float>(n[k]);
    for (int c = 0; c < 3; ++c) {
      const Vec3 p = corner(mesh, t, c) * scale;
      for (int k = 0; k < 3; ++k) record[static_cast<std::size_t>(3 + 3 * c + k)] = static_cast<float>(p[k]);
    }
    out.stream().write(reinterpret_cast<const char*>(record.data()), sizeof record);
    const std::uint16_t attribute = 0;
    out.stream().write(reinterpret_cast<const char*>(&attribute), sizeof attribute);
  }
  out.commit();
}

}  // namespace magvine::anatomy
