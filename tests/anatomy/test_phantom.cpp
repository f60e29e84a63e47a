// Generated phantoms: topology (watertight, one component, genus 0, outward), the bronchial tree's morphometry
// against the table it claims, volume against the branch cylinders, determinism and seeds, the constriction's gap
// measured on the mesh, graph nodes inside the lumen, files, and parameter errors.
// Meshing runs at coarse spacings here (0.5–1 mm) to stay fast; the default spacing is 0.4 mm.

#include "magvine/anatomy/phantom.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <unistd.h>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

constexpr double kTreeSpacing = 0.5e-3;   // coarsest the generator accepts for the default tree (gen 6 radius/2.8)
constexpr double kBenchSpacing = 0.6e-3;  // coarse but ≤ a quarter of a 2.4 mm feature
constexpr double kGeometryTol = 1e-12;    // [m, rad] exact table values through a few floating-point operations

// ---------------------------------------------------------------------------------------------------------------
// Helpers

Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Ericson, Real-Time Collision Detection, §5.1.5.
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// Brute-force nearest-triangle queries, bucketed on a uniform grid so a tree's mesh is searched in milliseconds.
class WallDistance {
 public:
  WallDistance(const TriangleMesh& mesh, double cell) : m_mesh(mesh), m_cell(cell) {
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      Vec3 lo = corner(mesh, t, 0), hi = lo;
      for (int k = 1; k < 3; ++k) {
        lo = lo.cwiseMin(corner(mesh, t, k));
        hi = hi.cwiseMax(corner(mesh, t, k));
      }
      const auto a = cell_of(lo), b = cell_of(hi);
      for (long i = a[0]; i <= b[0]; ++i)
        for (long j = a[1]; j <= b[1]; ++j)
          for (long k = a[2]; k <= b[2]; ++k) m_cells[key(i, j, k)].push_back(static_cast<std::uint32_t>(t));
    }
  }
  // Distance to the nearest triangle within `reach` (or `reach` if none), and whether p is behind that triangle
  // (inside the lumen, as normals point out).
  std::pair<double, bool> query(const Vec3& p, double reach) const {
    double best = reach;
    bool inside = false;
    const auto a = cell_of(p - Vec3::Constant(reach)), b = cell_of(p + Vec3::Constant(reach));
    for (long i = a[0]; i <= b[0]; ++i)
      for (long j = a[1]; j <= b[1]; ++j)
        for (long k = a[2]; k <= b[2]; ++k) {
          const auto it = m_cells.find(key(i, j, k));
          if (it == m_cells.end()) continue;
          for (const std::uint32_t t : it->second) {
            const Vec3 q = closest_on_triangle(p, corner(m_mesh, t, 0), corner(m_mesh, t, 1), corner(m_mesh, t, 2));
            const double d = (p - q).norm();
            if (d < best) {
              best = d;
              inside = (p - q).dot(area_vector(m_mesh, t)) < 0.0;
            }
          }
        }
    return {best, inside};
  }

 private:
  std::array<long, 3> cell_of(const Vec3& p) const {
    return {static_cast<long>(std::floor(p.x() / m_cell)), static_cast<long>(std::floor(p.y() / m_cell)),
            static_cast<long>(std::floor(p.z() / m_cell))};
  }
  static std::int64_t key(long i, long j, long k) { return (i + (1 << 20)) + ((j + (1 << 20)) << 21) + (static_cast<std::int64_t>(k + (1 << 20)) << 42); }
  const TriangleMesh& m_mesh;
  double m_cell;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> m_cells;
};

void expect_closed_genus_zero(const Phantom& phantom, const std::string& what) {
  const MeshReport r = analyse_mesh(phantom.mesh);
  EXPECT_EQ(r.boundary_edges, 0u) << what;
  EXPECT_EQ(r.non_manifold_edges, 0u) << what;
  EXPECT_TRUE(r.watertight) << what;
  EXPECT_EQ(r.components, 1u) << what;
  EXPECT_EQ(r.genus, 0) << what;
  EXPECT_EQ(r.orientation, Orientation::kOutward) << what;
  EXPECT_GT(signed_volume(phantom.mesh), 0.0) << what;
  EXPECT_NO_THROW(validate_graph(phantom.graph, what)) << what;
}

// Every graph node: inside the lumen, its wall distance at least half its radius (and at least the radius less one
// spacing: vertices lie within O(h²/r) < h of the true wall) and at most upper_factor × radius + one spacing.
void expect_nodes_inside(const Phantom& phantom, double spacing, double upper_factor, const std::string& what) {
  const WallDistance wall(phantom.mesh, 2e-3);
  for (std::size_t i = 0; i < phantom.graph.nodes.size(); ++i) {
    const AirwayNode& n = phantom.graph.nodes[i];
    const double reach = 2.0 * n.radius + 2.0 * spacing;
    const auto [d, inside] = wall.query(n.position, reach);
    EXPECT_TRUE(inside) << what << " node " << i;
    EXPECT_GE(d, std::max(0.5 * n.radius, n.radius - spacing)) << what << " node " << i;
    EXPECT_LE(d, upper_factor * n.radius + spacing) << what << " node " << i;
  }
}

Phantom tree_at(double spacing, double jitter = 0.0, std::uint64_t seed = 1, int generations = 6) {
  BronchialTreeParams p;
  p.spacing = spacing;
  p.max_generation = generations;
  p.length_jitter = jitter;
  p.angle_jitter = jitter * 0.5;
  p.rotation_jitter = jitter;
  p.seed = seed;
  return make_bronchial_tree(p);
}

Vec3 direction(const AirwayGraph& g, int b) {
  const AirwayBranch& br = g.branches[static_cast<std::size_t>(b)];
  return (g.nodes[br.nodes.back()].position - g.nodes[br.nodes.front()].position).normalized();
}

double branch_radius(const AirwayGraph& g, int b) {
  return g.nodes[g.branches[static_cast<std::size_t>(b)].nodes.back()].radius;
}

// The default tree is generated once for the suite (0.6 s at 0.5 mm).
class BronchialTree : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { s_tree = new Phantom(tree_at(kTreeSpacing)); }
  static void TearDownTestSuite() {
    delete s_tree;
    s_tree = nullptr;
  }
  static const Phantom& tree() { return *s_tree; }
  static Phantom* s_tree;
};
Phantom* BronchialTree::s_tree = nullptr;

// ---------------------------------------------------------------------------------------------------------------
// Kinds

TEST(Phantom, KindsAreListedParsedAndHaveDefaults) {
  const auto kinds = phantom_kinds();
  ASSERT_EQ(kinds.size(), 5u);
  for (const PhantomKindInfo& info : kinds) {
    EXPECT_EQ(parse_phantom_kind(info.name), info.kind);
    EXPECT_EQ(to_string(info.kind), info.name);
    EXPECT_FALSE(info.description.empty());
    EXPECT_EQ(default_params(info.kind).index(), static_cast<std::size_t>(info.kind));
  }
  EXPECT_EQ(parse_phantom_kind("bronchial-tree"), std::nullopt);
}

TEST(Phantom, EveryBenchKindIsClosedGenusZeroWithNodesInside) {
  // Bench kinds at a coarse spacing; node radii are inscribed-sphere radii, so the wall distance equals them up to
  // the grid's chord error (≤ one spacing) and the edge rounding.
  constexpr double kInscribedFactor = 1.05;
  std::vector<PhantomParams> kinds;
  kinds.emplace_back(TubeParams{});
  YBifurcationParams y;
  y.spacing = kBenchSpacing;
  kinds.emplace_back(y);
  SBendParams s;
  s.spacing = 1e-3;  // 20 mm high channel: 1 mm still gives 20 cells
  kinds.emplace_back(s);
  ConstrictionParams c;
  c.spacing = kBenchSpacing;
  c.gap = 3e-3;
  kinds.emplace_back(c);
  for (const PhantomParams& params : kinds) {
    const Phantom phantom = make_phantom(params);
    const std::string what(to_string(phantom.meta.kind));
    expect_closed_genus_zero(phantom, what);
    // The Y's bifurcation node carries the parent radius; the blend widens the lumen around it a little
    // (measured 1.04 r at 0.6 mm).
    const double upper = phantom.meta.kind == PhantomKind::kYBifurcation ? 1.1 : kInscribedFactor;
    expect_nodes_inside(phantom, std::holds_alternative<SBendParams>(params) ? 1e-3 : kBenchSpacing, upper, what);
  }
}

TEST(Phantom, TubeIsTheParametricTubeAlongX) {
  TubeParams p;
  const Phantom tube = make_tube_phantom(p);
  // Volume of the inscribed 64-gon prism: (n/2)·sin(2π/n)·r²·L, exact up to rounding.
  const double r = 0.5 * p.diameter;
  const double exact = 0.5 * p.segments * std::sin(2.0 * kPi / p.segments) * r * r * p.length;
  EXPECT_NEAR(signed_volume(tube.mesh), exact, 1e-12 * exact);
  const Aabb box = bounding_box(tube.mesh);
  EXPECT_NEAR(box.min.x(), 0.0, kGeometryTol);
  EXPECT_NEAR(box.max.x(), p.length, kGeometryTol);
  ASSERT_EQ(tube.graph.branches.size(), 1u);
  EXPECT_NEAR(branch_length(tube.graph, 0), p.length - 2.0 * r, kGeometryTol);
  p.capped = false;
  const MeshReport open = analyse_mesh(make_tube_phantom(p).mesh);
  EXPECT_EQ(open.openings.size(), 2u);
  EXPECT_FALSE(open.watertight);
}

// ---------------------------------------------------------------------------------------------------------------
// Bronchial tree

TEST_F(BronchialTree, IsClosedGenusZeroWithNodesInside) {
  expect_closed_genus_zero(tree(), "bronchial_tree");
  // A bifurcation node is the centre of the parent's end sphere: its wall is r_p away between the daughters, but
  // the blends of the parent and both daughters widen the lumen around it (measured up to 1.18 r at 0.5 mm).
  constexpr double kBifurcationWidening = 1.25;
  expect_nodes_inside(tree(), kTreeSpacing, kBifurcationWidening, "bronchial_tree");
}

TEST_F(BronchialTree, HasTwoToTheGBranchesPerGenerationWithTheTableGeometry) {
  const AirwayGraph& g = tree().graph;
  std::map<int, int> per_generation;
  for (const AirwayBranch& b : g.branches) ++per_generation[b.generation];
  ASSERT_EQ(per_generation.size(), 7u);
  for (int gen = 0; gen <= 6; ++gen) EXPECT_EQ(per_generation[gen], 1 << gen) << "generation " << gen;
  EXPECT_EQ(leaves(g).size(), 64u);
  for (const AirwayBranch& b : g.branches) {
    const GenerationGeometry expected = airway_table(AirwayTable::kWeibelA, b.generation);
    EXPECT_NEAR(branch_length(g, b.id), expected.length, kGeometryTol) << b.name;
    for (std::size_t k = 1; k < b.nodes.size(); ++k) {
      EXPECT_NEAR(g.nodes[b.nodes[k]].radius, 0.5 * expected.diameter, kGeometryTol) << b.name;
    }
    if (b.parent < 0) {
      EXPECT_NEAR(direction(g, b.id).dot(Vec3(0, 0, -1)), 1.0, kGeometryTol);  // trachea along −z
      continue;
    }
    const double angle = std::acos(std::clamp(direction(g, b.id).dot(direction(g, b.parent)), -1.0, 1.0));
    EXPECT_NEAR(angle, expected.branch_angle, 1e-9) << b.name;  // acos near 1 loses half the digits
  }
  // The branching plane turns 90° per generation: the normal of a bifurcation's plane is perpendicular to the
  // normal of its parent bifurcation's plane.
  for (const AirwayBranch& b : g.branches) {
    if (b.children.size() != 2 || b.parent < 0) continue;
    const AirwayBranch& p = g.branches[static_cast<std::size_t>(b.parent)];
    const Vec3 n_here = direction(g, b.children[0]).cross(direction(g, b.children[1])).normalized();
    const Vec3 n_parent = direction(g, p.children[0]).cross(direction(g, p.children[1])).normalized();
    EXPECT_NEAR(n_here.dot(n_parent), 0.0, 1e-12) << b.name;
  }
  // Default tree: no clearance adjustment was needed, so the table values hold everywhere.
  for (const std::string& note : tree().meta.notes) EXPECT_EQ(note.rfind("clearance", 0), std::string::npos) << note;
  // The trachea enters at the top: the mesh's highest point is the entry plane z = 0, one radius above node 0.
  EXPECT_NEAR(bounding_box(tree().mesh).max.z(), 0.0, 0.01 * kTreeSpacing);
  EXPECT_NEAR(g.nodes[0].position.z(), -9e-3, kGeometryTol);
}

TEST_F(BronchialTree, VolumeIsCloseToTheBranchCylinders) {
  // Reference: Σ πr²L over branches + the entry vestibule (one trachea radius of cylinder above node 0) + the leaf
  // hemispheres. Junctions add the parent's end hemisphere (Σ 4.2 cm³, 7 %) and lose the daughters' overlap with
  // it (at most 6.3 cm³, 10.6 %); the two nearly cancel: the net is −0.87 % at h = 0.2 mm. The grid's chords
  // lose O(h²): −0.25 % more at h = 0.5 mm. Allow 2 %; a missing generation (gen 6: 6 %) or a missing vestibule
  // (3.8 %) fails.
  constexpr double kVolumeTol = 0.02;
  const AirwayGraph& g = tree().graph;
  double reference = 0.0;
  for (const AirwayBranch& b : g.branches) {
    const double r = branch_radius(g, b.id);
    reference += kPi * r * r * branch_length(g, b.id);
    if (b.children.empty()) reference += 2.0 / 3.0 * kPi * r * r * r;
  }
  const double r0 = g.nodes[0].radius;
  reference += kPi * r0 * r0 * r0;
  const double volume = signed_volume(tree().mesh);
  EXPECT_NEAR(volume / reference, 1.0, kVolumeTol) << "mesh " << volume * 1e9 << " mm³, cylinders " << reference * 1e9;
}

TEST(Phantom, TreeIsDeterministicAndSeedsMatterOnlyWithJitter) {
  // Four generations at 0.5 mm keep this fast.
  const Phantom a = tree_at(kTreeSpacing, 0.0, 1, 4);
  const Phantom b = tree_at(kTreeSpacing, 0.0, 99, 4);  // another seed, no jitter: same tree
  ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
  EXPECT_TRUE(std::equal(a.mesh.vertices.begin(), a.mesh.vertices.end(), b.mesh.vertices.begin()));
  EXPECT_TRUE(std::equal(a.mesh.triangles.begin(), a.mesh.triangles.end(), b.mesh.triangles.begin()));

  const Phantom j1 = tree_at(kTreeSpacing, 0.2, 7, 4);
  const Phantom j2 = tree_at(kTreeSpacing, 0.2, 7, 4);
  const Phantom j3 = tree_at(kTreeSpacing, 0.2, 8, 4);
  ASSERT_EQ(j1.mesh.vertices.size(), j2.mesh.vertices.size());
  EXPECT_TRUE(std::equal(j1.mesh.vertices.begin(), j1.mesh.vertices.end(), j2.mesh.vertices.begin()));
  EXPECT_TRUE(std::equal(j1.mesh.triangles.begin(), j1.mesh.triangles.end(), j2.mesh.triangles.begin()));
  EXPECT_EQ(graph_to_json(j1.graph), graph_to_json(j2.graph));
  EXPECT_NE(graph_to_json(j1.graph), graph_to_json(j3.graph));
  EXPECT_NE(graph_to_json(j1.graph), graph_to_json(a.graph));
  EXPECT_FALSE(j1.mesh.vertices.size() == j3.mesh.vertices.size() &&
               std::equal(j1.mesh.vertices.begin(), j1.mesh.vertices.end(), j3.mesh.vertices.begin()));
  expect_closed_genus_zero(j3, "jittered tree");
}

TEST(Phantom, AsymmetricTreeFollowsKitaokaRules) {
  BronchialTreeParams p;
  p.flow_ratio = 0.3;
  p.max_generation = 4;
  p.spacing = kTreeSpacing;
  const Phantom t = make_bronchial_tree(p);
  expect_closed_genus_zero(t, "asymmetric tree");
  const AirwayGraph& g = t.graph;
  const double n = p.diameter_exponent;
  const double r = p.flow_ratio;
  // Minimum-power angles (Kitaoka et al. 1999), written out independently of the generator.
  const auto angle = [n](double q) {
    return std::acos((1.0 + std::pow(q, 4 / n) - std::pow(1 - q, 4 / n)) / (2.0 * std::pow(q, 2 / n)));
  };
  int checked = 0;
  for (const AirwayBranch& b : g.branches) {
    if (b.parent < 0) continue;
    const double d0 = 2.0 * branch_radius(g, b.parent);
    const bool major = b.name.back() == '0';
    const double q = major ? 1.0 - r : r;
    const double d = 2.0 * branch_radius(g, b.id);
    EXPECT_NEAR(d, d0 * std::pow(q, 1.0 / n), kGeometryTol) << b.name;
    const bool adjusted = std::any_of(t.meta.notes.begin(), t.meta.notes.end(), [&](const std::string& s) {
      return s.rfind("clearance: children of " + g.branches[static_cast<std::size_t>(b.parent)].name + " ", 0) == 0;
    });
    if (adjusted) continue;  // shortened for clearance: the angle still holds, the length not
    EXPECT_NEAR(branch_length(g, b.id), 3.0 * d, kGeometryTol) << b.name;
    const double a = std::acos(std::clamp(direction(g, b.id).dot(direction(g, b.parent)), -1.0, 1.0));
    EXPECT_NEAR(a, angle(q), 1e-9) << b.name;
    ++checked;
  }
  EXPECT_GT(checked, 20);
  // Symmetric split check of the formula itself: 34.9° (airways.md).
  EXPECT_NEAR(angle(0.5) / kDegToRad, 34.9, 0.05);
}

TEST(Phantom, ImpossibleClearanceFailsNamingTheBranches) {
  BronchialTreeParams p;
  p.clearance = 15e-3;
  p.spacing = kTreeSpacing;
  try {
    make_bronchial_tree(p);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("phantom bronchial_tree"), std::string::npos) << m;
    EXPECT_NE(m.find("clearance"), std::string::npos) << m;
    EXPECT_NE(m.find("branches 0-"), std::string::npos) << m;
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Constriction

TEST(Phantom, ConstrictionNarrowestWidthIsTheRequestedGap) {
  for (const double gap : {2e-3, 3.5e-3, 5e-3}) {
    ConstrictionParams p;
    p.gap = gap;
    p.spacing = 0.5e-3;
    const Phantom c = make_constriction(p);
    expect_closed_genus_zero(c, "constriction");
    // Measure on the mesh: over the flat part of the jaws (|x − x_c| < L/2 − rounding − h) and the middle half of
    // the slot's height, the walls are the vertices with y > 0 and y < 0; the width is their nearest approach.
    const double r = 0.5 * p.diameter;
    const double flat_half_x = 0.5 * p.constriction_length - p.jaw_rounding - p.spacing;
    const double half_height = 0.5 * std::sqrt(r * r - 0.25 * gap * gap);
    double upper = 1.0;
    double lower = -1.0;
    int samples = 0;
    for (const Vec3& v : c.mesh.vertices) {
      if (std::abs(v.x() - p.constriction_x) > flat_half_x || std::abs(v.z()) > half_height) continue;
      if (v.y() > 0) upper = std::min(upper, v.y());
      if (v.y() < 0) lower = std::max(lower, v.y());
      ++samples;
    }
    EXPECT_GT(samples, 100);
    // The jaw faces are planes where the field is linear, so edge interpolation puts vertices exactly on them; only
    // the end clamp (1e-3 of an edge ≤ √3 h) can move a vertex, towards the lumen or away.
    const double tol = 2.0 * 1e-3 * std::sqrt(3.0) * p.spacing;
    EXPECT_NEAR(upper - lower, gap, tol) << "gap " << gap * 1e3 << " mm";
    // The graph's radius at the constriction centre is half the gap.
    double centre_radius = 1.0;
    for (const AirwayNode& n : c.graph.nodes) {
      if (std::abs(n.position.x() - p.constriction_x) < 1e-12) centre_radius = n.radius;
    }
    EXPECT_NEAR(centre_radius, 0.5 * gap, kGeometryTol);
  }
}

TEST(Phantom, SBendBlocksTheStraightPathButLetsTheThesisRobotThrough) {
  SBendParams p;
  p.spacing = 1e-3;
  const Phantom s = make_s_bend(p);
  // A straight line from the entry node to the end node crosses the wall (both obstacles reach past y = 0).
  const Vec3 a = s.graph.nodes.front().position;
  const Vec3 b = s.graph.nodes.back().position;
  int crossings = 0;
  for (std::size_t t = 0; t < s.mesh.triangles.size(); ++t) {
    const Vec3 p0 = corner(s.mesh, t, 0), p1 = corner(s.mesh, t, 1), p2 = corner(s.mesh, t, 2);
    const Vec3 n = (p1 - p0).cross(p2 - p0);
    const double da = (a - p0).dot(n), db = (b - p0).dot(n);
    if ((da > 0) == (db > 0)) continue;
    const Vec3 x = a + (b - a) * (da / (da - db));
    if ((p1 - p0).cross(x - p0).dot(n) >= 0 && (p2 - p1).cross(x - p1).dot(n) >= 0 && (p0 - p2).cross(x - p2).dot(n) >= 0) {
      ++crossings;
    }
  }
  EXPECT_GE(crossings, 4);  // in and out of each obstacle
  // Along the graph the lumen never narrows below the thesis robot's Ø8 mm.
  constexpr double kRobotRadius = 4e-3;
  for (const AirwayNode& n : s.graph.nodes) EXPECT_GT(n.radius, kRobotRadius);
  // The path swings to +y around the first obstacle and to −y around the second.
  double max_y = 0.0, min_y = 0.0;
  for (const AirwayNode& n : s.graph.nodes) {
    max_y = std::max(max_y, n.position.y());
    min_y = std::min(min_y, n.position.y());
  }
  EXPECT_NEAR(max_y, 18e-3, kGeometryTol);
  EXPECT_NEAR(min_y, -18e-3, kGeometryTol);
}

// ---------------------------------------------------------------------------------------------------------------
// Files and errors

class PhantomFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    m_dir = std::filesystem::temp_directory_path() / ("magvine_phantom_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(m_dir);
  }
  void TearDown() override { std::filesystem::remove_all(m_dir); }
  std::filesystem::path m_dir;
};

TEST_F(PhantomFiles, WritesStlGraphAndMetadataInMillimetres) {
  YBifurcationParams p;
  p.spacing = 0.8e-3;
  const Phantom y = make_y_bifurcation(p);
  const auto stl = m_dir / "y.stl";
  write_phantom(y, stl);
  ASSERT_TRUE(std::filesystem::exists(stl));
  ASSERT_TRUE(std::filesystem::exists(m_dir / "y.graph.json"));
  ASSERT_TRUE(std::filesystem::exists(m_dir / "y.meta.json"));
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(m_dir)) ++files;
  EXPECT_EQ(files, 3u);  // no temporaries left
  EXPECT_EQ(std::filesystem::file_size(stl), 84u + 50u * y.mesh.triangles.size());

  std::ifstream meta_in(m_dir / "y.meta.json");
  const nlohmann::json meta = nlohmann::json::parse(meta_in);
  EXPECT_EQ(meta.at("units"), "mm");
  EXPECT_EQ(meta.at("kind"), "y_bifurcation");
  EXPECT_EQ(meta.at("triangles").get<std::size_t>(), y.mesh.triangles.size());
  EXPECT_NEAR(meta.at("parameters").at("parent_diameter_mm").get<double>(), 12.0, 1e-12);
  EXPECT_NEAR(meta.at("parameters").at("branch_angle_deg").get<double>(), 35.0, 1e-12);

  const AirwayGraph graph = read_graph(m_dir / "y.graph.json");
  ASSERT_EQ(graph.branches.size(), 3u);
  EXPECT_NEAR(branch_length(graph, 1), p.daughter_length, 1e-12);

  // The STL (float mm) reads back as the same closed mesh.
  const ImportedMesh back = import_mesh(stl);
  EXPECT_EQ(back.mesh.triangles.size(), y.mesh.triangles.size());
  const MeshReport r = analyse_mesh(back.mesh);
  EXPECT_TRUE(r.watertight);
  EXPECT_EQ(r.genus, 0);
  // Float coordinates in mm: relative 6e-8 of ~0.1 m, summed over the volume integral.
  EXPECT_NEAR(signed_volume(back.mesh), signed_volume(y.mesh), 1e-5 * signed_volume(y.mesh));
}

TEST(Phantom, BadParametersNameTheParameter) {
  const auto message_of = [](const PhantomParams& params) -> std::string {
    try {
      make_phantom(params);
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  ConstrictionParams c;
  c.gap = 13e-3;
  EXPECT_NE(message_of(c).find("gap_mm"), std::string::npos) << message_of(c);
  c.gap = 1e-3;  // finer than a quarter of the default spacing allows
  EXPECT_NE(message_of(c).find("spacing_mm"), std::string::npos) << message_of(c);
  BronchialTreeParams t;
  t.max_generation = 11;
  EXPECT_NE(message_of(t).find("max_generation"), std::string::npos) << message_of(t);
  t.max_generation = 6;
  t.spacing = 0.8e-3;
  EXPECT_NE(message_of(t).find("spacing_mm"), std::string::npos) << message_of(t);
  t.spacing = 0.4e-3;
  t.table = AirwayTable::kHorsfield;
  t.max_generation = 7;
  EXPECT_NE(message_of(t).find("max_generation"), std::string::npos) << message_of(t);
  SBendParams s;
  s.obstacle_reach = 55e-3;
  EXPECT_NE(message_of(s).find("obstacle_reach_mm"), std::string::npos) << message_of(s);
  TubeParams u;
  u.diameter = -1.0;
  EXPECT_NE(message_of(u).find("diameter_mm"), std::string::npos) << message_of(u);
}

}  // namespace
}  // namespace magvine::anatomy
