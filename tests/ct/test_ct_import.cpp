// CT import (ct/segmentation.hpp, ct/import.hpp): label maps written byte by byte (support/nifti_file.hpp) come back
// as closed surfaces in the right world place — spheres against their closed form in anisotropic and oblique grids,
// the LPS frame as the RAS one turned about z — bad files get one clear message, and the five Med-MPD segmentations
// import against the shared marching-cubes meshes (skipped without ../shared/airways).

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>

#include "magvine/anatomy/biopsy_plan.hpp"
#include "magvine/anatomy/breathing.hpp"
#include "magvine/anatomy/mesh_distance.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/core/error.hpp"
#include "magvine/ct/import.hpp"
#include "magvine/scene/experiment.hpp"
#include "support/airways.hpp"
#include "support/mesh_distance.hpp"
#include "support/nifti_file.hpp"
#include "support/text_file.hpp"

namespace magvine::ct {
namespace {

const std::filesystem::path kWork = std::filesystem::temp_directory_path() / "magvine_test_ct_import";

std::filesystem::path written(const std::string& name, const test::NiftiLabels& labels) {
  std::filesystem::create_directories(kWork);
  const std::filesystem::path path = kWork / name;
  test::write_nifti(path, labels);
  return path;
}

/// A ball of `radius_mm` about the world point `centre_mm` (label 1), in the grid of `l`.
void ball(test::NiftiLabels& l, const std::array<double, 3>& centre_mm, double radius_mm, float label = 1.0f) {
  if (l.values.empty()) test::fill(l, [](int, int, int) { return 0.0f; });
  std::size_t n = 0;
  for (int k = 0; k < l.dims[2]; ++k) {
    for (int j = 0; j < l.dims[1]; ++j) {
      for (int i = 0; i < l.dims[0]; ++i, ++n) {
        const auto p = test::voxel_to_world(l, i, j, k);
        const double d2 =
            std::pow(p[0] - centre_mm[0], 2) + std::pow(p[1] - centre_mm[1], 2) + std::pow(p[2] - centre_mm[2], 2);
        if (d2 <= radius_mm * radius_mm) l.values[n] = label;
      }
    }
  }
}

/// Area-weighted centroid of a surface [m] (adaptive meshing makes vertex density uneven, so not the vertex mean).
Vec3 surface_centroid(const anatomy::TriangleMesh& mesh) {
  Vec3 c = Vec3::Zero();
  double area = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const double a = 0.5 * area_vector(mesh, t).norm();
    c += a * (corner(mesh, t, 0) + corner(mesh, t, 1) + corner(mesh, t, 2)) / 3.0;
    area += a;
  }
  return c / area;
}

std::string error_of(const std::filesystem::path& file, int label = 1) {
  try {
    SurfaceOptions options;
    options.label = label;
    (void)import_segmentation(file, options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

// An anisotropic grid 0.5 × 0.5 × 0.8 mm in scanner coordinates: the ball comes back as a closed genus-0 sphere
// where the qform puts it, of the right size. Tolerances: the voxel surface of the map deviates from the sphere by
// up to half a voxel (0.25-0.4 mm) locally but not on average; the import may move it by another half voxel at
// most (the smoothing's clamp), so the mean radius within 0.1 mm (a quarter voxel) and the volume within 5 %
// (3·0.1/6) are what a correct import gives and what a wrong frame, a lost half-voxel or shrinking would break.
TEST(CtImport, BallInAnisotropicGridLiesWhereTheQformPutsIt) {
  test::NiftiLabels l;
  l.dims = {40, 40, 26};
  l.voxel_mm = {0.5f, 0.5f, 0.8f};
  l.offset_mm = {-120.0f, 40.0f, 1100.0f};
  const std::array<double, 3> centre = {-110.2, 49.7, 1110.1};
  const double radius = 6.0;
  ball(l, centre, radius);
  SurfaceReport report;
  const anatomy::TriangleMesh mesh = import_segmentation(written("ball.nii", l), {}, &report);
  const anatomy::MeshReport check = anatomy::analyse_mesh(mesh);
  EXPECT_TRUE(check.watertight);
  EXPECT_EQ(check.genus, 0);
  EXPECT_EQ(check.orientation, anatomy::Orientation::kOutward);
  EXPECT_EQ(report.frame_source, "qform");
  ASSERT_EQ(report.notes.size(), 1u);
  EXPECT_NE(report.notes[0].find("anisotropic"), std::string::npos) << report.notes[0];
  EXPECT_NEAR(report.voxel, 0.5e-3, 1e-12);
  const Vec3 c(centre[0] * 1e-3, centre[1] * 1e-3, centre[2] * 1e-3);
  EXPECT_LT((surface_centroid(mesh) - c).norm(), 0.1e-3);
  double mean_r = 0.0;
  for (const Vec3& v : mesh.vertices) mean_r += (v - c).norm();
  mean_r /= static_cast<double>(mesh.vertices.size());
  EXPECT_NEAR(mean_r, radius * 1e-3, 0.1e-3);
  const double sphere = 4.0 / 3.0 * std::numbers::pi * std::pow(radius * 1e-3, 3);
  EXPECT_NEAR(*check.volume / sphere, 1.0, 0.05);
}

// LPS is RAS turned 180° about z: every vertex (x, y, z) becomes (−x, −y, z), nothing else changes.
TEST(CtImport, LpsIsRasTurnedAboutZ) {
  test::NiftiLabels l;
  l.dims = {24, 24, 24};
  l.voxel_mm = {0.6f, 0.6f, 0.6f};
  l.offset_mm = {10.0f, -20.0f, 30.0f};
  ball(l, {16.9, -13.1, 36.9}, 4.0);
  const std::filesystem::path file = written("lps.nii", l);
  SurfaceOptions lps;
  lps.frame = Frame::kLps;
  const anatomy::TriangleMesh a = import_segmentation(file, {});
  const anatomy::TriangleMesh b = import_segmentation(file, lps);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  for (std::size_t n = 0; n < a.vertices.size(); ++n) {
    EXPECT_EQ(b.vertices[n], Vec3(-a.vertices[n].x(), -a.vertices[n].y(), a.vertices[n].z()));
  }
  EXPECT_EQ(a.triangles, b.triangles);
}

// A grid turned 30° about z (qform quaternion): a rod along the grid's i axis comes out along the turned axis, and
// the note says the grid is oblique. Tolerance 1°: the rod is 30 voxels long and 6 across, so its principal axis
// is fixed to well under a degree by its ends.
TEST(CtImport, ObliqueGridTurnsTheSurface) {
  test::NiftiLabels l;
  l.dims = {40, 16, 16};
  l.voxel_mm = {0.5f, 0.5f, 0.5f};
  const double half = 15.0 * std::numbers::pi / 180.0;
  l.quaternion = {std::cos(half), 0.0, 0.0, std::sin(half)};
  test::fill(l,
             [](int i, int j, int k) { return i >= 5 && i < 35 && std::hypot(j - 7.5, k - 7.5) <= 3.2 ? 1.0f : 0.0f; });
  SurfaceReport report;
  const anatomy::TriangleMesh mesh = import_segmentation(written("oblique.nii", l), {}, &report);
  EXPECT_NEAR(report.obliquity_deg, 30.0, 1e-3);
  ASSERT_FALSE(report.notes.empty());
  EXPECT_NE(report.notes.back().find("oblique"), std::string::npos);
  const Vec3 mean = surface_centroid(mesh);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& v : mesh.vertices) cov += (v - mean) * (v - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Vec3 axis = eig.eigenvectors().col(2);
  const double angle = std::atan2(std::abs(axis.y()), std::abs(axis.x())) * 180.0 / std::numbers::pi;
  EXPECT_NEAR(angle, 30.0, 1.0);
  EXPECT_NEAR(axis.z(), 0.0, 0.02);
}

// Two separate balls: the larger is kept, with a warning naming the dropped part's size.
TEST(CtImport, KeepsTheLargestComponentWithAWarning) {
  test::NiftiLabels l;
  l.dims = {50, 24, 24};
  l.voxel_mm = {0.5f, 0.5f, 0.5f};
  ball(l, {6.0, 6.0, 6.0}, 4.5);
  ball(l, {19.0, 6.0, 6.0}, 2.5);
  SurfaceReport report;
  const anatomy::TriangleMesh mesh = import_segmentation(written("two.nii", l), {}, &report);
  ASSERT_EQ(report.components.size(), 2u);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("2 disconnected"), std::string::npos) << report.warnings[0];
  EXPECT_NE(report.warnings[0].find(std::to_string(report.components[1])), std::string::npos);
  EXPECT_EQ(anatomy::analyse_mesh(mesh).components, 1u);
  EXPECT_LT((surface_centroid(mesh) - Vec3(6e-3, 6e-3, 6e-3)).norm(), 0.1e-3);
}

// A hollow ball (unlabelled voxels enclosed by the label): the cavity's surface would be an obstacle inside the
// lumen, so none may be left. The rebuilt level set fills enclosed regions (OpenVDB's mesh-to-volume floods the
// sign from outside), so the hollow ball's surface is the solid ball's, triangle for triangle.
TEST(CtImport, LeavesNoCavityInsideTheLumen) {
  test::NiftiLabels solid;
  solid.dims = {30, 30, 30};
  solid.voxel_mm = {0.5f, 0.5f, 0.5f};
  ball(solid, {7.25, 7.25, 7.25}, 6.0);
  test::NiftiLabels hollow = solid;
  ball(hollow, {7.25, 7.25, 7.25}, 2.0, 0.0f);
  ASSERT_NE(hollow.values, solid.values);
  const anatomy::TriangleMesh a = import_segmentation(written("hollow.nii", hollow), {});
  const anatomy::TriangleMesh b = import_segmentation(written("solid.nii", solid), {});
  EXPECT_EQ(anatomy::analyse_mesh(a).components, 1u);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.vertices, b.vertices);
}

// Bad files: one message naming the file and what is wrong.
TEST(CtImport, BadFilesGetOneClearMessage) {
  std::filesystem::create_directories(kWork);
  { std::ofstream(kWork / "text.nii.gz") << "not a label map\n"; }
  EXPECT_NE(error_of(kWork / "text.nii.gz").find("not a NIfTI file"), std::string::npos);
  EXPECT_NE(error_of(kWork / "missing.nii").find("no such file"), std::string::npos);

  test::NiftiLabels l;
  l.dims = {8, 8, 8};
  test::fill(l, [](int i, int, int) { return i < 4 ? 0.0f : 3.0f; });
  const std::string absent = error_of(written("label3.nii", l), 1);
  EXPECT_NE(absent.find("label3.nii"), std::string::npos) << absent;
  EXPECT_NE(absent.find("no voxel carries label 1"), std::string::npos) << absent;
  EXPECT_NE(absent.find("0 (256 voxels), 3 (256 voxels)"), std::string::npos) << absent;

  test::NiftiLabels four = l;
  four.nt = 2;
  four.values.insert(four.values.end(), l.values.begin(), l.values.end());
  EXPECT_NE(error_of(written("four.nii", four), 3).find("4-D image"), std::string::npos);

  test::NiftiLabels intensity = l;
  intensity.as_float = true;
  intensity.values[5] = 0.5f;
  EXPECT_NE(error_of(written("intensity.nii", intensity), 3).find("fractional"), std::string::npos);
}

// anatomy::surface_distance against the brute-force reference (every triangle, tests/support/mesh_distance.hpp) on
// the same samples: the BVH query must find the nearest triangle exactly.
TEST(CtImport, SurfaceDistanceMatchesBruteForce) {
  test::NiftiLabels l;
  l.dims = {24, 24, 24};
  l.voxel_mm = {0.6f, 0.6f, 0.6f};
  ball(l, {7.0, 7.0, 7.0}, 4.5);
  const anatomy::TriangleMesh a = import_segmentation(written("a.nii", l), {});
  SurfaceOptions raw;
  raw.smoothing = 0;
  raw.adaptivity = 0.0;
  const anatomy::TriangleMesh b = import_segmentation(written("a.nii", l), raw);
  const test::BruteForceDistance brute(b);
  double weight = 0.0, sum = 0.0, max = 0.0;
  for (std::size_t t = 0; t < a.triangles.size(); ++t) {
    const double area = 0.5 * area_vector(a, t).norm();
    const Vec3 c = (corner(a, t, 0) + corner(a, t, 1) + corner(a, t, 2)) / 3.0;
    const double dc = brute.point(c).distance;
    sum += 0.5 * area * dc;
    max = std::max(max, dc);
    for (int k = 0; k < 3; ++k) {
      const double d = brute.point(corner(a, t, k)).distance;
      sum += area / 6.0 * d;
      max = std::max(max, d);
    }
    weight += area;
  }
  const anatomy::SurfaceDistance d = anatomy::surface_distance(a, anatomy::CollisionWorld(b));
  EXPECT_NEAR(d.mean, sum / weight, 1e-12);
  EXPECT_NEAR(d.max, max, 1e-12);
  EXPECT_GT(d.mean, 0.0);
}

// `anatomy: {segmentation: FILE}` in a scene: the bundled Y scene with its phantom swapped for a capped tube of
// radius 5 mm given as a label map. The scene's anatomy is the imported surface (closed) with its extracted graph,
// the tube's radius within half a voxel (the import's bound); a missing label is an error naming the key.
TEST(CtImport, ScenesTakeASegmentation) {
  test::NiftiLabels l;
  l.dims = {30, 30, 100};
  l.voxel_mm = {0.5f, 0.5f, 0.7f};
  test::fill(l, [](int i, int j, int k) {
    return std::hypot(i * 0.5 - 7.25, j * 0.5 - 7.25) <= 5.0 && k * 0.7 >= 5.0 && k * 0.7 <= 65.0 ? 1.0f : 0.0f;
  });
  const std::filesystem::path file = written("tube.nii", l);
  const std::string text =
      "units: {length: mm, pressure: kPa}\n"
      "anatomy:\n"
      "  segmentation: " +
      file.string() +
      "\n"
      "robot:\n"
      "  kind: vine\n"
      "  length: 5\n"
      "  diameter: 5\n"
      "  pressure: 35\n"
      "  wall: {thickness: 0.038, youngs_modulus: 10000, density: 1100, strength: 2900}\n"
      "  fill: {kind: magnetic_fluid, volume_fraction: 0.23}\n"
      "  base: {position: [7.25, 7.25, 10], direction: [0, 0, 1], normal: [1, 0, 0]}\n"
      "growth: {yield_pressure: 20}\n"
      "control: {pressure: [[0, 35]]}\n"
      "simulation: {duration: 1, dt: 0.02}\n";
  const scene::ExperimentScene sc = scene::parse_experiment_scene(text, "ct.yaml", MAGVINE_SOURCE_DIR);
  EXPECT_TRUE(sc.anatomy->closed);
  EXPECT_EQ(sc.anatomy->label, file.string());
  ASSERT_TRUE(sc.anatomy->graph.has_value());
  ASSERT_FALSE(sc.anatomy->graph->branches.empty());
  const auto& trunk = sc.anatomy->graph->branches.front();
  const double r = sc.anatomy->graph->nodes[trunk.nodes[trunk.nodes.size() / 2]].radius;
  EXPECT_NEAR(r, 5e-3, 0.35e-3);

  std::string bad = text;
  const std::string given = "segmentation: " + file.string();
  bad.replace(bad.find(given), given.size(), given + "\n  label: 9");
  try {
    (void)scene::parse_experiment_scene(bad, "ct.yaml", MAGVINE_SOURCE_DIR);
    ADD_FAILURE() << "a missing label must be refused";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("anatomy.segmentation"), std::string::npos) << what;
    EXPECT_NE(what.find("no voxel carries label 9"), std::string::npos) << what;
  }
}

// The five Med-MPD segmentations (acceptance of issue 31): each imports watertight with a graph to generation ≥ 5
// and a trachea 13-22 mm across (adult tracheal diameters: Breatnach et al., AJR 1984, coronal 13-25 mm in men,
// 10-21 in women).
class RealSegmentation : public ::testing::TestWithParam<int> {};

TEST_P(RealSegmentation, ImportsClosedWithATreeToGenerationFive) {
  const int patient = GetParam();
  const auto file = ::test::airway_file("segmentations/Patient" + std::to_string(patient) + "/bronchialTree.nii.gz");
  if (!file) GTEST_SKIP() << "../shared/airways/segmentations absent";
  const ImportResult r = import_anatomy(*file);
  EXPECT_TRUE(r.report.watertight);
  EXPECT_EQ(r.report.components, 1u);
  EXPECT_GE(r.deepest_generation, 5);
  EXPECT_GE(r.trachea_diameter, 13e-3);
  EXPECT_LE(r.trachea_diameter, 22e-3);
  std::cout << "patient " << patient << ": " << r.report.triangles << " triangles, genus " << r.report.genus
            << ", trachea " << 1e3 * r.trachea_diameter << " mm, generations 0-" << r.deepest_generation << ", "
            << r.seconds_total << " s\n";
  // The planning problem's nodule (target.txt, RAS mm): where a Ø5 and a Ø3 mm robot would stop.
  std::ifstream target(file->parent_path() / "target.txt");
  Vec3 nodule;
  target >> nodule.x() >> nodule.y() >> nodule.z();
  ASSERT_TRUE(target) << "target.txt";
  nodule *= 1e-3;
  const anatomy::CollisionWorld world(r.mesh.mesh);
  EXPECT_FALSE(world.contains(nodule));
  // The dataset's start poses lie on the bronchial wall, aimed at the nodule by a steerable-needle planner: the
  // nearest one's straight distance to the nodule is an independent figure for the needle path. The plan for a
  // Ø3 mm tool must come within 15 % of it (its stops are limited to branches the tool fits and to a 60° turn, the
  // dataset's are not).
  double dataset = std::numeric_limits<double>::infinity();
  for (int k = 1; k <= 5; ++k) {
    std::ifstream pose(file->parent_path() / ("start" + std::to_string(k) + ".txt"));
    double m[16];
    for (double& v : m) pose >> v;
    if (pose) dataset = std::min(dataset, 1e-3 * (Vec3(m[3], m[7], m[11]) - 1e3 * nodule).norm());
  }
  ASSERT_TRUE(std::isfinite(dataset));
  for (const double tool : {2.5e-3, 1.5e-3}) {
    const anatomy::BiopsyPlan p =
        anatomy::plan_biopsy(r.graph, world, nodule, {.tool_radius = tool, .max_needle = 0.2});
    ASSERT_TRUE(p.found) << p.why;
    const anatomy::AirwayBranch& b = r.graph.branches[static_cast<std::size_t>(p.branch)];
    std::cout << "  Ø" << 2e3 * tool << " mm: stop in " << b.name << " (generation " << b.generation << ", lumen Ø"
              << 2e3 * p.lumen_radius << " mm), needle " << 1e3 * p.needle << " mm at "
              << p.angle * 180.0 / std::numbers::pi << " deg; the dataset's nearest start " << 1e3 * dataset << " mm\n";
    if (tool == 1.5e-3) {
      EXPECT_LE(p.needle, 1.15 * dataset);
    }
  }
  // Breathing (anatomy/breathing.hpp, defaults, superior = +z in RAS): how far the nodule moves between full
  // inspiration (the CT) and exhalation, against Chen et al.'s 17.6 mm average (more than 20 mm in the lower lobes).
  anatomy::BreathingParams breathing;
  breathing.entry = r.graph.nodes[r.graph.branches.front().nodes.front()].position;
  breathing.carina = r.graph.nodes[r.graph.branches.front().nodes.back()].position;
  const double moves = anatomy::breathing_amplitude(breathing, nodule);
  std::cout << "  breathing: carina " << 1e3 * breathing_amplitude(breathing, breathing.carina) << " mm, nodule "
            << 1e3 * (breathing.carina - nodule).z() << " mm below the carina moves " << 1e3 * moves << " mm\n";
  // Measured: 22, 11.9, 22, 22 mm and 4.4 mm for patient 5's nodule 8 mm above the carina (an upper-lobe nodule:
  // tumours 4 (3) mm, PMC4476088); mean 16.5 mm against Chen's 17.6 mm.
  EXPECT_GT(moves, 0.0);
  EXPECT_LE(moves, breathing.lower_amplitude);
}

INSTANTIATE_TEST_SUITE_P(Patients, RealSegmentation, ::testing::Values(1, 2, 3, 4, 5));

// Patients 1 and 5 against the shared marching-cubes meshes of the same maps (level ½, unsmoothed): mean surface
// distance below one voxel and volume within 10 % (the acceptance figures of issue 31: the reference carries the
// ±½-voxel staircase that the import smooths away, so neither can be zero).
class AgainstMarchingCubes : public ::testing::TestWithParam<std::pair<int, std::string>> {};

TEST_P(AgainstMarchingCubes, WithinOneVoxelAndTenPercentOfVolume) {
  const auto [patient, mesh_name] = GetParam();
  const auto file = ::test::airway_file("segmentations/Patient" + std::to_string(patient) + "/bronchialTree.nii.gz");
  const auto reference = ::test::airway_file(mesh_name);
  if (!file || !reference) GTEST_SKIP() << "../shared/airways absent";
  SurfaceReport report;
  const anatomy::TriangleMesh mesh = import_segmentation(*file, {}, &report);
  const anatomy::TriangleMesh ref = anatomy::import_mesh(*reference).mesh;
  const double finest = std::min({report.spacing[0], report.spacing[1], report.spacing[2]});
  const anatomy::SurfaceDistance d = anatomy::symmetric_surface_distance(mesh, ref);
  const double volume = std::abs(anatomy::signed_volume(mesh)) / std::abs(anatomy::signed_volume(ref));
  EXPECT_LT(d.mean, finest);
  EXPECT_NEAR(volume, 1.0, 0.10);
  std::cout << "patient " << patient << ": mean distance " << 1e3 * d.mean << " mm (" << d.mean / finest
            << " voxel), max " << 1e3 * d.max << " mm, volume ratio " << volume << "\n";
}

INSTANTIATE_TEST_SUITE_P(Patients, AgainstMarchingCubes,
                         ::testing::Values(std::pair<int, std::string>{1, "lidc0297_medmpd_p1_airway_mc.stl"},
                                           std::pair<int, std::string>{5, "lidc0525_medmpd_p5_airway_mc.stl"}));

}  // namespace
}  // namespace magvine::ct
