// Airway graph extraction (issue 8) against the generated phantoms' ground-truth graphs: topology, centreline
// distance and radii; and against the VMTK centrelines of a real phantom when ../shared/airways is there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include <fstream>
#include <sstream>

#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "support/airways.hpp"

namespace magvine::anatomy {
namespace {

TEST(Centerline, TheComparisonSeesAChangedTopologyAnOffsetAndAWrongRadius) {
  // The metric itself: a graph against itself is exact; one branch fewer changes the shape; moving every node by
  // 10 % of the radius across the branch and scaling the radii by 1.2 read as 0.1 and 0.2.
  const Phantom y = make_y_bifurcation({});
  const GraphComparison self = compare_graphs(y.graph, y.graph);
  EXPECT_TRUE(self.same_topology);
  EXPECT_EQ(self.mean_distance, 0.0);
  EXPECT_EQ(self.mean_radius_error, 0.0);
  AirwayGraph moved = y.graph;
  for (auto& n : moved.nodes) {
    n.position.z() += 0.1 * n.radius;  // the Y lies in the x-y plane: z is across every branch
    n.radius *= 1.2;
  }
  const GraphComparison off = compare_graphs(moved, y.graph);
  EXPECT_NEAR(off.mean_distance, 0.1, 1e-9);
  EXPECT_NEAR(off.mean_radius_error, 0.2, 1e-9);
  AirwayGraph fewer;
  for (int b = 0; b < 2; ++b) {
    std::vector<std::uint32_t> ids;
    for (const auto n : y.graph.branches[static_cast<std::size_t>(b)].nodes) {
      ids.push_back(add_node(fewer, y.graph.nodes[n].position, y.graph.nodes[n].radius));
    }
    if (b == 1) ids.front() = fewer.branches[0].nodes.back();
    add_branch(fewer, b == 0 ? -1 : 0, ids);
  }
  EXPECT_FALSE(compare_graphs(fewer, y.graph).same_topology);
}

TEST(Centerline, TheYBifurcationsGraph) {
  const Phantom y = make_y_bifurcation({});
  CenterlineReport report;
  const AirwayGraph g = extract_airway_graph(y.mesh, {}, &report);
  const GraphComparison c = compare_graphs(g, y.graph);
  std::cout << "[ Y ] voxel " << 1e3 * report.voxel << " mm, " << report.inside_voxels << " voxels, "
            << g.branches.size() << " branches, spurs " << report.spurs_pruned << "; centreline distance "
            << 100 * c.mean_distance << " % of the radius, radius error mean " << 100 * c.mean_radius_error
            << " %, p95 " << 100 * c.p95_radius_error << " % (" << 100 * c.p95_radius_error_away
            << " % away from junctions and ends); " << report.seconds << " s\n";
  EXPECT_TRUE(c.same_topology) << graph_shape(g);
  EXPECT_LT(c.mean_distance, 0.10);
  EXPECT_LT(c.mean_radius_error, 0.10);
  EXPECT_LT(c.p95_radius_error_away, 0.10);
}

TEST(Centerline, TheBronchialTreesGraphToGenerationSix) {
  BronchialTreeParams p;
  p.max_generation = 6;
  const Phantom tree = make_bronchial_tree(p);
  CenterlineReport report;
  const AirwayGraph g = extract_airway_graph(tree.mesh, {}, &report);
  const GraphComparison c = compare_graphs(g, tree.graph);
  std::cout << "[ tree g6 ] voxel " << 1e3 * report.voxel << " mm, " << report.inside_voxels << " voxels, "
            << g.branches.size() << " branches (truth " << tree.graph.branches.size() << "), spurs "
            << report.spurs_pruned << "; centreline distance " << 100 * c.mean_distance
            << " % of the radius, radius error mean " << 100 * c.mean_radius_error << " %, p95 "
            << 100 * c.p95_radius_error << " % (" << 100 * c.p95_radius_error_away
            << " % away from junctions and ends); " << report.seconds << " s\n";
  EXPECT_TRUE(c.same_topology) << graph_shape(g);
  EXPECT_LT(c.mean_distance, 0.10);
  EXPECT_LT(c.mean_radius_error, 0.10);
  EXPECT_LT(c.p95_radius_error_away, 0.10);
}

/// Polylines of an OBJ file's `l` records [m] (the file in mm).
std::vector<std::vector<Vec3>> obj_polylines(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::vector<Vec3> v;
  std::vector<std::vector<Vec3>> lines;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v") {
      double x = 0, y = 0, z = 0;
      s >> x >> y >> z;
      v.push_back(1e-3 * Vec3(x, y, z));
    } else if (tag == "l") {
      std::vector<Vec3> pl;
      long i = 0;
      while (s >> i) pl.push_back(v[static_cast<std::size_t>(i - 1)]);
      lines.push_back(std::move(pl));
    }
  }
  return lines;
}

double distance_to_lines(const std::vector<std::vector<Vec3>>& lines, const Vec3& x) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& pl : lines) {
    for (std::size_t i = 0; i + 1 < pl.size(); ++i) {
      const Vec3 d = pl[i + 1] - pl[i];
      const double u = std::clamp((x - pl[i]).dot(d) / std::max(d.squaredNorm(), 1e-30), 0.0, 1.0);
      best = std::min(best, (x - (pl[i] + u * d)).norm());
    }
  }
  return best;
}

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

TEST(Centerline, ARealPhantomAgainstItsVmtkCentrelines) {
  const auto mesh_file = test::airway_file("siliconmodel3_airway.stl");
  const auto lines_file = test::airway_file("siliconmodel3_centerlines.obj");
  if (!mesh_file || !lines_file) GTEST_SKIP() << "../shared/airways (siliconmodel3) is absent";
  const TriangleMesh mesh = import_mesh(*mesh_file).mesh;
  CenterlineReport report;
  const AirwayGraph g = extract_airway_graph(mesh, {}, &report);
  const auto vmtk = obj_polylines(*lines_file);
  ASSERT_EQ(vmtk.size(), 60u);
  std::vector<std::vector<Vec3>> ours;
  for (const auto& b : g.branches) {
    std::vector<Vec3> pl;
    for (const auto n : b.nodes) pl.push_back(g.nodes[n].position);
    ours.push_back(std::move(pl));
  }
  // Centreline distances both ways [mm].
  std::vector<double> to_ours, to_vmtk;
  for (const auto& pl : vmtk) {
    for (const Vec3& x : pl) to_ours.push_back(1e3 * distance_to_lines(ours, x));
  }
  for (const auto& n : g.nodes) to_vmtk.push_back(1e3 * distance_to_lines(vmtk, n.position));
  double mean_ours = 0.0, mean_vmtk = 0.0;
  for (double d : to_ours) mean_ours += d / static_cast<double>(to_ours.size());
  for (double d : to_vmtk) mean_vmtk += d / static_cast<double>(to_vmtk.size());
  // Leaves: VMTK's leaf end of each polyline (the end away from the shared root end) against our leaf branches'
  // ends; matched when within 5 mm (ours stop one radius short of the end wall, VMTK's at it), one to one.
  const Vec3 root_a = vmtk[0].front(), root_b = vmtk[0].back();
  const bool front_is_root = (vmtk[1].front() - root_a).norm() < 1e-3 || (vmtk[1].back() - root_a).norm() < 1e-3;
  const Vec3 root = front_is_root ? root_a : root_b;
  std::vector<Vec3> vmtk_leaves;
  for (const auto& pl : vmtk) vmtk_leaves.push_back((pl.front() - root).norm() > (pl.back() - root).norm() ? pl.front() : pl.back());
  std::vector<Vec3> our_leaves;
  for (const int b : leaves(g)) our_leaves.push_back(g.nodes[g.branches[static_cast<std::size_t>(b)].nodes.back()].position);
  std::vector<bool> used(our_leaves.size(), false);
  int matched = 0;
  for (const Vec3& l : vmtk_leaves) {
    int best = -1;
    double best_d = 5e-3;
    for (std::size_t k = 0; k < our_leaves.size(); ++k) {
      const double d = (our_leaves[k] - l).norm();
      if (!used[k] && d < best_d) {
        best_d = d;
        best = static_cast<int>(k);
      }
    }
    if (best >= 0) {
      used[static_cast<std::size_t>(best)] = true;
      ++matched;
    }
  }
  std::cout << "[ siliconmodel3 ] voxel " << 1e3 * report.voxel << " mm, " << report.seconds << " s, "
            << g.branches.size() << " branches, " << our_leaves.size() << " leaves (VMTK 60)\n"
            << "  VMTK points to our graph: mean " << mean_ours << " mm, p95 " << percentile(to_ours, 0.95)
            << " mm; our nodes to VMTK: mean " << mean_vmtk << " mm, p95 " << percentile(to_vmtk, 0.95)
            << " mm; leaves matched within 5 mm: " << matched << " / 60\n";
  // Bounds that catch a broken extraction, not fitted to the result: the phantom's lumens are 2–18 mm across, so
  // a graph that strays from VMTK's by more than about a small airway's radius on average is wrong somewhere.
  EXPECT_LT(mean_ours, 1.5);
  EXPECT_LT(mean_vmtk, 1.5);
  EXPECT_GE(matched, 45);
}

}  // namespace
}  // namespace magvine::anatomy
