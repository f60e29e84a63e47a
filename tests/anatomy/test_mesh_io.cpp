// Import through assimp: STL round trip, formats, units and pose, welding, the real CT meshes in ../shared/airways
// against the counts and sizes in their SOURCES.md, and one-line errors for files that cannot be used.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/error.hpp"
#include "support/airways.hpp"

namespace magvine::anatomy {
namespace {

namespace fs = std::filesystem;

// STL stores single-precision floats: a coordinate of magnitude x (in file units) survives to ~6e-8·x.
constexpr double kFloatRelative = 1.2e-7;

class MeshIo : public ::testing::Test {
 protected:
  void SetUp() override {
    m_dir = fs::temp_directory_path() /
            ("magvine_mesh_io_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(m_dir);
    fs::create_directories(m_dir);
  }
  void TearDown() override { fs::remove_all(m_dir); }
  fs::path write(const std::string& name, const std::string& text) const {
    std::ofstream(m_dir / name, std::ios::binary) << text;
    return m_dir / name;
  }
  fs::path m_dir;
};

std::string error_of(const fs::path& path, const MeshImportOptions& options = {}) {
  try {
    import_mesh(path, options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST_F(MeshIo, BinaryStlRoundTripKeepsTopologyAndCoordinates) {
  const TriangleMesh tube = make_tube({.radius = 6e-3, .length = 0.04, .segments = 40, .rings = 0, .capped = true});
  const fs::path stl = m_dir / "tube.stl";
  write_stl(stl, tube);  // millimetres
  const ImportedMesh in = import_mesh(stl, {.units = LengthUnit::kMm});
  EXPECT_EQ(in.stats.raw_triangles, tube.triangles.size());
  EXPECT_EQ(in.stats.raw_vertices, 3 * tube.triangles.size());  // STL repeats every corner
  EXPECT_EQ(in.mesh.triangles.size(), tube.triangles.size());
  EXPECT_EQ(in.mesh.vertices.size(), tube.vertices.size());     // welded back to the shared vertices
  EXPECT_EQ(in.stats.degenerate_removed, 0u);
  EXPECT_TRUE(in.warnings.empty());
  // Same triangles in the same order; corners agree to float precision.
  for (std::size_t t = 0; t < tube.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE((corner(in.mesh, t, k) - corner(tube, t, k)).norm(), kFloatRelative * 0.04) << t;
    }
  }
  const MeshReport report = analyse_mesh(in.mesh);
  EXPECT_TRUE(report.watertight);
  EXPECT_EQ(report.genus, 0);
  EXPECT_NEAR(*report.volume, signed_volume(tube), 3 * kFloatRelative * signed_volume(tube));
}

TEST_F(MeshIo, UnitsScaleAndPoseAreApplied) {
  const TriangleMesh tube = make_tube({.radius = 6e-3, .length = 0.04, .segments = 24, .rings = 0, .capped = true});
  const fs::path stl = m_dir / "tube_cm.stl";
  write_stl(stl, tube, LengthUnit::kCm);
  const Aabb truth = bounding_box(tube);
  const Aabb cm = bounding_box(import_mesh(stl, {.units = LengthUnit::kCm}).mesh);
  EXPECT_NEAR(cm.max.z(), truth.max.z(), kFloatRelative * 0.04);
  // The same numbers declared as mm are ten times smaller; declared as m, 100× larger and flagged implausible.
  const Aabb mm = bounding_box(import_mesh(stl, {.units = LengthUnit::kMm}).mesh);
  EXPECT_NEAR(mm.max.z(), truth.max.z() / 10.0, kFloatRelative * 0.04);
  const ImportedMesh metres = import_mesh(stl, {.units = LengthUnit::kM});
  EXPECT_NEAR(bounding_box(metres.mesh).max.z(), truth.max.z() * 100.0, kFloatRelative * 4.0);
  ASSERT_EQ(metres.warnings.size(), 1u);
  EXPECT_NE(metres.warnings[0].find("implausible"), std::string::npos);
  EXPECT_NE(metres.warnings[0].find("--units"), std::string::npos);
  // Pose: rotate +z onto +x and shift; scale doubles first.
  MeshImportOptions posed{.units = LengthUnit::kCm, .scale = 2.0};
  posed.pose = Eigen::Translation3d(0.1, 0.2, 0.3) * Eigen::AngleAxisd(kPi / 2, Vec3::UnitY());
  const Aabb moved = bounding_box(import_mesh(stl, posed).mesh);
  EXPECT_NEAR(moved.max.x(), 0.1 + 2.0 * truth.max.z(), 1e-6);
  EXPECT_NEAR(moved.min.x(), 0.1, 1e-6);
  EXPECT_NEAR(moved.max.z() - moved.min.z(), 2.0 * (truth.max.x() - truth.min.x()), 1e-6);
}

TEST_F(MeshIo, AsciiStlObjPlyOffAndGltfReadTheSameTetrahedron) {
  // One tetrahedron (outward winding) in five text formats; OBJ uses a quad-free polygon list, PLY/OFF a triangle
  // list. Each must give 4 triangles, 4 vertices after welding, volume 1/6 (mm³ → m³).
  const std::string stl =
      "solid t\n"
      "facet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n"
      "facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n"
      "facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n"
      "facet normal 1 1 1\nouter loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\n"
      "endsolid t\n";
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  const std::string off = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  // glTF 2.0 with the buffer inline (base64 of 12 little-endian float32 positions, then 12 uint16 indices in the
  // PLY order above; 72 bytes).
  const std::string gltf = R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
    "buffers": [{"byteLength": 72, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAACAAEAAAABAAMAAAADAAIAAQACAAMA"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 24}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]},
                  {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}]})";
  for (const auto& [name, text] :
       {std::pair{"t.stl", stl}, {"t.obj", obj}, {"t.ply", ply}, {"t.off", off}, {"t.gltf", gltf}}) {
    SCOPED_TRACE(name);
    const ImportedMesh in = import_mesh(write(name, text), {.units = LengthUnit::kMm});
    EXPECT_EQ(in.mesh.triangles.size(), 4u);
    EXPECT_EQ(in.mesh.vertices.size(), 4u);
    const MeshReport r = analyse_mesh(in.mesh);
    EXPECT_TRUE(r.watertight);
    EXPECT_EQ(r.orientation, Orientation::kOutward);
    EXPECT_NEAR(*r.volume, 1e-9 / 6.0, 1e-9 / 6.0 * 1e-12);
  }
}

TEST_F(MeshIo, ObjQuadsAreTriangulatedAndNodesMerged) {
  // A unit cube of six quads in two OBJ objects: 12 triangles, 8 vertices, volume 1 mm³.
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
      "o bottom_and_sides\nf 1 4 3 2\nf 1 2 6 5\nf 2 3 7 6\n"
      "o top_and_rest\nf 3 4 8 7\nf 4 1 5 8\nf 5 6 7 8\n";
  const ImportedMesh in = import_mesh(write("cube.obj", obj));
  EXPECT_EQ(in.mesh.triangles.size(), 12u);
  EXPECT_EQ(in.mesh.vertices.size(), 8u);
  EXPECT_GE(in.stats.meshes_merged, 2u);
  const MeshReport r = analyse_mesh(in.mesh);
  EXPECT_TRUE(r.watertight);
  EXPECT_NEAR(*r.volume, 1e-9, 1e-9 * 1e-12);
}

TEST_F(MeshIo, DegenerateAndDuplicateTrianglesAreRemovedAndCounted) {
  // The tetrahedron plus a repeated face (reversed winding), a collapsed face and a collinear sliver.
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0.5 0 0\n"
      "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 2 3 1\nf 1 1 2\nf 1 5 2\n";
  const ImportedMesh in = import_mesh(write("dirty.obj", obj));
  EXPECT_EQ(in.stats.raw_triangles, 7u);
  EXPECT_EQ(in.stats.duplicate_removed, 1u);
  EXPECT_EQ(in.stats.degenerate_removed, 2u);
  EXPECT_EQ(in.mesh.triangles.size(), 4u);
  EXPECT_EQ(in.mesh.vertices.size(), 4u);  // the sliver's midpoint vertex is no longer used
}

TEST_F(MeshIo, BadFilesFailWithOneLineNamingTheFile) {
  const TriangleMesh tube = make_tube({.radius = 6e-3, .length = 0.04, .segments = 16, .rings = 0, .capped = true});
  const fs::path good = m_dir / "good.stl";
  write_stl(good, tube);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  TriangleMesh nan_mesh = tube;
  nan_mesh.vertices[3].x() = std::numeric_limits<double>::quiet_NaN();
  write_stl(m_dir / "nan.stl", nan_mesh);
  std::string zero_count = bytes.substr(0, 80) + std::string(4, '\0');
  fs::create_directories(m_dir / "folder.stl");

  const std::vector<std::pair<fs::path, std::string>> cases = {
      {write("empty.stl", ""), "empty"},
      {write("truncated.stl", bytes.substr(0, bytes.size() / 2)), "cannot read"},
      {m_dir / "nan.stl", "non-finite"},
      {write("zero.stl", zero_count), ""},
      {write("mesh.xyz", bytes), "unsupported file extension"},
      {write("mesh.vtk", "# vtk DataFile Version 3.0\nfoo\nBINARY\nDATASET POLYDATA\n"), "legacy VTK"},
      {m_dir / "folder.stl", "directory"},
      {m_dir / "missing.stl", "not found"},
      {write("garbage.obj", "this is not\x01\x02 a mesh\n"), ""},
  };
  for (const auto& [path, expected] : cases) {
    SCOPED_TRACE(path.filename().string());
    const std::string message = error_of(path);
    ASSERT_FALSE(message.empty()) << "no error";
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    if (!expected.empty()) {
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
  }
  EXPECT_NE(error_of(good, {.units = LengthUnit::kMm, .scale = -1.0}).find("scale"), std::string::npos);
}

// Every mesh in ../shared/airways with the counts, topology and sizes its SOURCES.md lists.
struct RealMesh {
  const char* file;
  std::size_t triangles;
  long genus;
  double volume_cm3;
  Vec3 extent_mm;
};

TEST(RealAirways, ImportWithTheCountsAndSizesOfSourcesMd) {
  const RealMesh meshes[] = {
      {"siliconmodel3_airway.stl", 74584, 0, 71.1, Vec3(185.8, 111.4, 260.1)},
      {"lidc0525_medmpd_p5_airway_mc.stl", 195274, 81, 42.9, Vec3(161.7, 105.3, 206.5)},
      {"lidc0297_medmpd_p1_airway_mc.stl", 161372, 29, 43.9, Vec3(141.0, 84.3, 238.7)},
  };
  int found = 0;
  for (const RealMesh& m : meshes) {
    const auto path = test::airway_file(m.file);
    if (!path) continue;
    ++found;
    SCOPED_TRACE(m.file);
    const ImportedMesh in = import_mesh(*path, {.units = LengthUnit::kMm});
    const MeshReport r = analyse_mesh(in.mesh);
    EXPECT_EQ(r.triangles, m.triangles);
    EXPECT_TRUE(r.watertight);
    EXPECT_EQ(r.components, 1u);
    EXPECT_EQ(r.genus, m.genus);
    EXPECT_EQ(r.orientation, Orientation::kOutward);
    EXPECT_TRUE(in.warnings.empty());
    // SOURCES.md rounds to 0.1 cm³ and 0.1 mm.
    EXPECT_NEAR(*r.volume * 1e6, m.volume_cm3, 0.05);
    const Vec3 extent = (r.bbox.max - r.bbox.min) / kMmToM;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(extent[k], m.extent_mm[k], 0.05);
  }
  if (found == 0) GTEST_SKIP() << "../shared/airways not present";
}

TEST(RealAirways, LegacyVtkAndCenterlineObjGetClearMessages) {
  const auto vtk = test::airway_file("siliconmodel3_airway.vtk");
  const auto obj = test::airway_file("siliconmodel3_centerlines.obj");
  if (!vtk || !obj) GTEST_SKIP() << "../shared/airways not present";
  const std::string vtk_message = error_of(*vtk);
  EXPECT_NE(vtk_message.find("legacy VTK"), std::string::npos);
  EXPECT_NE(vtk_message.find("STL, OBJ or PLY"), std::string::npos);
  EXPECT_NE(error_of(*obj).find("no triangles"), std::string::npos);
}

}  // namespace
}  // namespace magvine::anatomy
