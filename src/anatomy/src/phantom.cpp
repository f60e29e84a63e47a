#include "magvine/anatomy/phantom.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "magvine/anatomy/implicit_surface.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/segment_geometry.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {

namespace {

using nlohmann::json;

// Largest branching angle a clearance adjustment may widen to [rad].
constexpr double kMaxBranchAngle = 80.0 * kDegToRad;
// Largest distance between consecutive graph nodes along a straight branch [m]: fine enough for targets and
// along-path metrics, coarse enough to keep the graph small.
constexpr double kGraphNodeSpacing = 5e-3;
// Node spacing along the bench channels' curved / varying centre lines [m].
constexpr double kBenchNodeSpacing = 2e-3;
// Finest meshing grid accepted from parameters [m]; finer grids exceed memory for a tree.
constexpr double kMinSpacing = 0.05e-3;

constexpr std::array<PhantomKindInfo, 5> kKinds{{
    {PhantomKind::kBronchialTree, "bronchial_tree",
     "symmetric (Weibel A / Horsfield) or Kitaoka-asymmetric bronchial tree, trachea to generation 6 by default"},
    {PhantomKind::kTube, "tube", "straight circular tube, 12 mm x 120 mm by default"},
    {PhantomKind::kYBifurcation, "y_bifurcation", "one symmetric bifurcation: 12 mm parent, 9.5 mm daughters at 35 deg"},
    {PhantomKind::kSBend, "s_bend", "flat 160 x 60 x 20 mm channel with two obstacles forcing an S-shaped path"},
    {PhantomKind::kConstriction, "constriction", "12 mm tube squeezed by flat jaws to a slot of adjustable gap"},
}};

// ---------------------------------------------------------------------------------------------------------------
// Parameter checks.

std::string source_of(PhantomKind kind) { return "phantom " + std::string(to_string(kind)); }

std::string format_number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// Throws InputError unless lo ≤ value ≤ hi (value and range in file units: `scale` converts SI to them).
void require_range(PhantomKind kind, const std::string& name, double value, double lo, double hi, double scale,
                   const std::string& unit) {
  if (std::isfinite(value) && value >= lo && value <= hi) return;
  throw InputError(source_of(kind), 0, name,
                   "must be in [" + format_number(lo * scale) + ", " + format_number(hi * scale) + "]" + unit +
                       " (got " + format_number(value * scale) + unit + ")");
}

void require_length(PhantomKind kind, const std::string& name_mm, double value, double lo, double hi) {
  require_range(kind, name_mm, value, lo, hi, 1.0 / kMmToM, " mm");
}

void require_spacing(PhantomKind kind, double spacing, double finest_feature, const std::string& feature) {
  require_length(kind, "spacing_mm", spacing, kMinSpacing, 1e9);
  if (spacing > finest_feature) {
    throw InputError(source_of(kind), 0, "spacing_mm",
                     "must be <= " + format_number(finest_feature / kMmToM) + " mm to resolve " + feature + " (got " +
                         format_number(spacing / kMmToM) + " mm)");
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Small geometry helpers.

// Deterministic uniform numbers in [−1, 1] (splitmix64, Steele et al. 2014): portable, unlike std distributions.
class Jitter {
 public:
  explicit Jitter(std::uint64_t seed) : m_state(seed) {}
  double next() {
    std::uint64_t z = (m_state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return 2.0 * (static_cast<double>(z >> 11) * 0x1.0p-53) - 1.0;
  }

 private:
  std::uint64_t m_state;
};

// Wall gap between capsules A and B (axis distance − both radii) counted only between axis points outside the
// capsule M that joins them (A and B are second-degree relatives: grandparent/grandchild or uncle/nephew, both
// touching M). Where both axes are inside M the space between them is M's lumen, so they may approach or overlap
// there without making a tunnel. Axes are sampled every ≤ 0.1 mm; the sampling overestimates the gap by at most
// 0.05 mm.
double gap_outside(const Vec3& a0, const Vec3& a1, double ra, const Vec3& b0, const Vec3& b1, double rb,
                   const Vec3& m0, const Vec3& m1, double rm) {
  constexpr double kStep = 0.1e-3;
  const auto samples = [&](const Vec3& p0, const Vec3& p1) {
    std::vector<Vec3> out;
    const int n = std::max(2, static_cast<int>(std::ceil((p1 - p0).norm() / kStep)) + 1);
    for (int i = 0; i < n; ++i) {
      const Vec3 q = p0 + (p1 - p0) * (static_cast<double>(i) / (n - 1));
      if ((q - closest_point_on_segment(q, m0, m1)).norm() >= rm) out.push_back(q);
    }
    return out;
  };
  const std::vector<Vec3> sa = samples(a0, a1);
  const std::vector<Vec3> sb = samples(b0, b1);
  double gap = std::numeric_limits<double>::infinity();
  for (const Vec3& qa : sa) {
    for (const Vec3& qb : sb) gap = std::min(gap, (qa - qb).norm() - ra - rb);
  }
  return gap;
}

Vec3 rotate_about(const Vec3& v, const Vec3& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()) * v;
}

// ---------------------------------------------------------------------------------------------------------------
// Trees of straight capsule branches (bronchial tree, Y): plan → field + graph.

struct PlannedBranch {
  int parent = -1;
  int generation = 0;
  Vec3 start = Vec3::Zero();          // graph start (the parent's end for a child) [m]
  Vec3 end = Vec3::Zero();            // [m]
  Vec3 children_normal = Vec3::UnitY();  // normal of the plane the children will lie in
  double radius = 0.0;                // [m]
  double blend = 0.0;                 // smooth-union blend radius [m]
};

/// Equal steps of at most `step` covering `length` (at least one; a length that is an exact multiple gets no extra).
int subdivisions(double length, double step) { return std::max(1, static_cast<int>(std::ceil(length / step - 1e-9))); }

// Graph with straight branches subdivided every ≤ kGraphNodeSpacing; a bifurcation node keeps the parent's
// radius (it is the centre of the parent's end sphere).
AirwayGraph graph_of(const std::vector<PlannedBranch>& plan) {
  AirwayGraph graph;
  std::vector<std::uint32_t> end_node(plan.size());
  for (std::size_t i = 0; i < plan.size(); ++i) {
    const PlannedBranch& b = plan[i];
    std::vector<std::uint32_t> nodes;
    nodes.push_back(b.parent < 0 ? add_node(graph, b.start, b.radius) : end_node[static_cast<std::size_t>(b.parent)]);
    const double length = (b.end - b.start).norm();
    const int segments = subdivisions(length, kGraphNodeSpacing);
    for (int k = 1; k <= segments; ++k) {
      nodes.push_back(add_node(graph, b.start + (b.end - b.start) * (static_cast<double>(k) / segments), b.radius));
    }
    end_node[i] = nodes.back();
    add_branch(graph, b.parent, std::move(nodes));
  }
  return graph;
}

// The lumen: one blend group per bifurcation (the parent and its children), so a branch blends with its parent
// and siblings only; the root's capsule starts at `entry` (one radius before its first node) and is cut flat
// there, perpendicular to the root.
CompositeSdf field_of(const std::vector<PlannedBranch>& plan, const Vec3& entry) {
  std::vector<std::vector<std::size_t>> children(plan.size());
  for (std::size_t i = 1; i < plan.size(); ++i) children[static_cast<std::size_t>(plan[i].parent)].push_back(i);
  const auto capsule = [&](std::size_t i) {
    const PlannedBranch& b = plan[i];
    return RoundCone{b.parent < 0 ? entry : b.start, b.end, b.radius, b.radius};
  };
  CompositeSdf field;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    if (children[i].empty()) continue;
    const int group = static_cast<int>(i);
    field.add_lumen(capsule(i), plan[i].blend, group);
    for (const std::size_t c : children[i]) field.add_lumen(capsule(c), plan[c].blend, group);
  }
  const Vec3 root_direction = (plan.front().end - plan.front().start).normalized();
  field.add_clip(entry, -root_direction);
  return field;
}


double deg(double rad) { return rad / kDegToRad; }

// Kitaoka et al. 1999 rule 6: minimum-power branching angle of the daughter carrying flow fraction r.
double kitaoka_angle(double r, double n) {
  const double c = (1.0 + std::pow(r, 4.0 / n) - std::pow(1.0 - r, 4.0 / n)) / (2.0 * std::pow(r, 2.0 / n));
  return std::acos(std::clamp(c, -1.0, 1.0));
}


}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Kinds

std::span<const PhantomKindInfo> phantom_kinds() { return kKinds; }

std::optional<PhantomKind> parse_phantom_kind(std::string_view name) {
  for (const PhantomKindInfo& info : kKinds) {
    if (info.name == name) return info.kind;
  }
  return std::nullopt;
}

std::string_view to_string(PhantomKind kind) {
  for (const PhantomKindInfo& info : kKinds) {
    if (info.kind == kind) return info.name;
  }
  return "unknown";
}

PhantomParams default_params(PhantomKind kind) {
  switch (kind) {
    case PhantomKind::kBronchialTree: return BronchialTreeParams{};
    case PhantomKind::kTube: return TubeParams{};
    case PhantomKind::kYBifurcation: return YBifurcationParams{};
    case PhantomKind::kSBend: return SBendParams{};
    case PhantomKind::kConstriction: return ConstrictionParams{};
  }
  return TubeParams{};
}

std::vector<PhantomOption> phantom_options(PhantomParams& params) {
  const auto length = [](const char* name, double& f, const char* help) {
    return PhantomOption{std::string(name) + "_mm", std::string(help) + " [mm]", &f, kMmToM};
  };
  const auto angle = [](const char* name, double& f, const char* help) {
    return PhantomOption{std::string(name) + "_deg", std::string(help) + " [deg]", &f, kDegToRad};
  };
  const auto number = [](const char* name, double& f, const char* help) { return PhantomOption{name, help, &f, 1.0}; };
  if (auto* p = std::get_if<BronchialTreeParams>(&params)) {
    return {{"max_generation", "deepest generation (trachea = 0)", &p->max_generation, 1.0},
            number("flow_ratio", p->flow_ratio, "Kitaoka flow-dividing ratio r in [0.2, 0.5]; 0.5 = symmetric"),
            number("diameter_exponent", p->diameter_exponent, "Kitaoka diameter exponent n in [2, 4]"),
            number("length_jitter", p->length_jitter, "relative half-range of the branch-length jitter, [0, 0.5)"),
            angle("angle_jitter", p->angle_jitter, "half-range of the branching-angle jitter"),
            angle("rotation_jitter", p->rotation_jitter, "half-range of the jitter on the 90 deg plane rotation"),
            {"seed", "seed of the jitter", &p->seed, 1.0},
            length("clearance", p->clearance, "minimum wall gap between non-adjacent branches"),
            number("blend_factor", p->blend_factor, "junction blend radius / branch radius, [0, 1]"),
            length("spacing", p->spacing, "meshing grid spacing")};
  }
  if (auto* p = std::get_if<TubeParams>(&params)) {
    return {length("diameter", p->diameter, "inner diameter"),
            length("length", p->length, "length along +x"),
            {"segments", "vertices around the circumference", &p->segments, 1.0}};
  }
  if (auto* p = std::get_if<YBifurcationParams>(&params)) {
    return {length("parent_diameter", p->parent_diameter, "parent tube diameter"),
            length("parent_length", p->parent_length, "first graph node to the bifurcation"),
            length("daughter_diameter", p->daughter_diameter, "daughter diameter"),
            length("daughter_length", p->daughter_length, "bifurcation to the blind end"),
            angle("branch_angle", p->branch_angle, "each daughter's angle to the parent axis"),
            number("blend_factor", p->blend_factor, "junction blend radius / daughter radius"),
            length("spacing", p->spacing, "meshing grid spacing")};
  }
  if (auto* p = std::get_if<SBendParams>(&params)) {
    return {length("length", p->length, "channel length along x"),
            length("width", p->width, "channel width along y"),
            length("height", p->height, "channel height along z"),
            length("obstacle_thickness", p->obstacle_thickness, "obstacle size along x"),
            length("obstacle_reach", p->obstacle_reach, "how far each obstacle reaches from its side wall"),
            length("first_obstacle_x", p->first_obstacle_x, "centre of the first obstacle (from the -y wall)"),
            length("second_obstacle_x", p->second_obstacle_x, "centre of the second obstacle (from the +y wall)"),
            length("edge_rounding", p->edge_rounding, "rounding radius of the channel's edges"),
            length("spacing", p->spacing, "meshing grid spacing")};
  }
  auto& c = std::get<ConstrictionParams>(params);
  return {length("diameter", c.diameter, "tube inner diameter"),
          length("length", c.length, "tube length along x"),
          length("gap", c.gap, "slot width at the constriction"),
          length("constriction_length", c.constriction_length, "jaw length along x"),
          length("constriction_x", c.constriction_x, "jaw centre along x"),
          length("jaw_rounding", c.jaw_rounding, "rounding radius of the jaw edges"),
          length("spacing", c.spacing, "meshing grid spacing")};
}

// ---------------------------------------------------------------------------------------------------------------
// Airway tables (shared/reference/airways.md §1; Tu, Inthavong & Ahmadi 2013, Tables 3.2 and 3.3).

GenerationGeometry airway_table(AirwayTable table, int generation) {
  // Weibel A, generations 0–10 [mm] (0–6 checked, 7–10 recalled in airways.md).
  static constexpr std::array<double, 11> kWeibelDiameter{18.0, 12.2, 8.3, 5.6, 4.5, 3.5, 2.8, 2.3, 1.86, 1.54, 1.30};
  static constexpr std::array<double, 11> kWeibelLength{120, 47.6, 19.0, 7.6, 12.7, 10.7, 9.0, 7.6, 6.4, 5.4, 4.6};
  // Horsfield 1994, generations 0–6 [mm, deg].
  static constexpr std::array<double, 7> kHorsfieldDiameter{16.5, 12.0, 8.5, 6.1, 4.4, 3.6, 2.9};
  static constexpr std::array<double, 7> kHorsfieldLength{91, 38, 15, 8.3, 9.0, 8.1, 6.6};
  static constexpr std::array<double, 7> kHorsfieldAngle{0, 36, 35, 28, 35, 39, 34};
  // Beyond Horsfield's angles: the customary 35° (airways.md: "users commonly assume about 35°").
  constexpr double kDefaultAngleDeg = 35.0;
  if (generation < 0 || generation > airway_table_depth(table)) {
    throw std::out_of_range("airway_table: generation " + std::to_string(generation) + " outside the table");
  }
  const auto g = static_cast<std::size_t>(generation);
  const double angle = g < kHorsfieldAngle.size() ? kHorsfieldAngle[g] : kDefaultAngleDeg;
  if (table == AirwayTable::kWeibelA) {
    return {kWeibelDiameter[g] * kMmToM, kWeibelLength[g] * kMmToM, angle * kDegToRad};
  }
  return {kHorsfieldDiameter[g] * kMmToM, kHorsfieldLength[g] * kMmToM, angle * kDegToRad};
}

std::string_view to_string(AirwayTable table) { return table == AirwayTable::kWeibelA ? "weibel_a" : "horsfield"; }

std::optional<AirwayTable> parse_airway_table(std::string_view name) {
  for (const AirwayTable table : {AirwayTable::kWeibelA, AirwayTable::kHorsfield}) {
    if (name == to_string(table)) return table;
  }
  return std::nullopt;
}

int airway_table_depth(AirwayTable table) { return table == AirwayTable::kWeibelA ? 10 : 6; }

// ---------------------------------------------------------------------------------------------------------------
// Bronchial tree

Phantom make_bronchial_tree(const BronchialTreeParams& p) {
  constexpr PhantomKind kind = PhantomKind::kBronchialTree;
  const int depth = airway_table_depth(p.table);
  if (p.max_generation < 1 || p.max_generation > depth) {
    throw InputError(source_of(kind), 0, "max_generation",
                     "must be in [1, " + std::to_string(depth) + "] for the " + std::string(to_string(p.table)) +
                         " table (got " + std::to_string(p.max_generation) + ")");
  }
  require_range(kind, "flow_ratio", p.flow_ratio, 0.2, 0.5, 1.0, "");
  require_range(kind, "diameter_exponent", p.diameter_exponent, 2.0, 4.0, 1.0, "");
  require_range(kind, "length_jitter", p.length_jitter, 0.0, 0.49, 1.0, "");
  require_range(kind, "angle_jitter_deg", p.angle_jitter, 0.0, 0.35, 1.0 / kDegToRad, " deg");
  require_range(kind, "rotation_jitter_deg", p.rotation_jitter, 0.0, 0.8, 1.0 / kDegToRad, " deg");
  require_range(kind, "blend_factor", p.blend_factor, 0.0, 1.0, 1.0, "");
  require_length(kind, "clearance_mm", p.clearance, 0.0, 20e-3);

  const bool symmetric = p.flow_ratio >= 0.5;
  const double n = p.diameter_exponent;
  Jitter jitter(p.seed);

  // Trachea: table values, along −z, first node one radius below the flat entry at z = 0.
  const GenerationGeometry g0 = airway_table(p.table, 0);
  std::vector<PlannedBranch> plan;
  {
    PlannedBranch trachea;
    trachea.radius = 0.5 * g0.diameter;
    trachea.blend = p.blend_factor * trachea.radius;
    trachea.start = Vec3(0, 0, -trachea.radius);
    trachea.end = trachea.start + g0.length * Vec3(0, 0, -1);
    trachea.children_normal = Vec3(0, -1, 0);  // children in the x–z plane, child 0 towards +x
    plan.push_back(trachea);
  }
  std::vector<std::string> notes;
  notes.emplace_back(p.table == AirwayTable::kWeibelA
                         ? "diameters and lengths: Weibel (1963) model A, generations 0-6 as tabulated by Tu, "
                           "Inthavong & Ahmadi (2013) Table 3.2; branching angles: Horsfield (1994), Table 3.3; 35 "
                           "deg beyond generation 6"
                         : "diameters, lengths and branching angles: Horsfield (1994), Tu, Inthavong & Ahmadi (2013) "
                           "Table 3.3");
  if (!symmetric) {
    notes.emplace_back("below the trachea: Kitaoka, Takaki & Suki (1999) rules: d = d0 r^(1/n), minimum-power "
                       "angles, L = 3 d; child 0 is the major daughter");
  }
  notes.emplace_back("branching plane turned 90 deg about the parent axis at every generation");
  notes.emplace_back("graph: the trachea's first node is one trachea radius below the flat entry at z = 0; a "
                     "bifurcation node carries the parent's radius");

  // Names for messages, built like add_branch does.
  std::vector<std::string> names{"0"};

  // The first branch that `b` (index `self` in the plan, or −1 while being placed) comes closer to than the
  // clearance, or −1. Adjacent branches (parent, siblings, own children) are skipped; the grandparent and the
  // parent's siblings, which touch the parent as well, only count outside the parent's capsule (gap_outside).
  const auto conflict_with = [&](const PlannedBranch& b, int self) -> int {
    const int parent_of_b = b.parent;
    for (std::size_t jj = 0; jj < plan.size(); ++jj) {
      const int j = static_cast<int>(jj);
      const PlannedBranch& other = plan[jj];
      if (j == self || j == parent_of_b) continue;
      if (parent_of_b >= 0 && other.parent == parent_of_b) continue;  // sibling
      if (self >= 0 && other.parent == self) continue;                // own child
      const double plain =
          segment_distance(b.start, b.end, other.start, other.end) - b.radius - other.radius;
      if (plain >= p.clearance) continue;
      if (parent_of_b >= 0) {
        const PlannedBranch& m = plan[static_cast<std::size_t>(parent_of_b)];
        const bool second_degree = j == m.parent || (m.parent >= 0 && other.parent == m.parent);
        if (second_degree &&
            gap_outside(b.start, b.end, b.radius, other.start, other.end, other.radius, m.start, m.end, m.radius) >=
                p.clearance) {
          continue;
        }
      }
      return j;
    }
    return -1;
  };

  std::vector<int> frontier{0};
  for (int generation = 1; generation <= p.max_generation; ++generation) {
    std::vector<int> next;
    for (const int parent_id : frontier) {
      const double parent_radius = plan[static_cast<std::size_t>(parent_id)].radius;
      // Daughter diameters, lengths and angles, before jitter. Child 0 is the major daughter when asymmetric.
      std::array<double, 2> diameter{};
      std::array<double, 2> length{};
      std::array<double, 2> angle{};
      if (symmetric) {
        const GenerationGeometry g = airway_table(p.table, generation);
        diameter = {g.diameter, g.diameter};
        length = {g.length, g.length};
        angle = {g.branch_angle, g.branch_angle};
      } else {
        const double d0 = 2.0 * parent_radius;
        const double r = p.flow_ratio;
        diameter = {d0 * std::pow(1.0 - r, 1.0 / n), d0 * std::pow(r, 1.0 / n)};
        length = {3.0 * diameter[0], 3.0 * diameter[1]};
        angle = {kitaoka_angle(1.0 - r, n), kitaoka_angle(r, n)};
      }
      // Jitter: three draws per child, always taken, so the sequence does not depend on which jitter is on.
      std::array<double, 2> child_rotation{};
      for (std::size_t k = 0; k < 2; ++k) {
        length[k] *= 1.0 + p.length_jitter * jitter.next();
        angle[k] += p.angle_jitter * jitter.next();
        child_rotation[k] = p.rotation_jitter * jitter.next();
      }

      // Find the first pose that keeps clearance from every non-adjacent branch: the parent as planned or
      // lengthened (moves the bifurcation away from its neighbours), the pair's plane turned about the parent axis,
      // and each child independently shortened and/or its branching angle narrowed or widened. The orders are fixed,
      // so the result is deterministic.
      constexpr std::array<double, 4> kParentExtensions{1.0, 1.15, 1.3, 1.5};
      constexpr std::array<double, 13> kTurnsDeg{0, 15, -15, 30, -30, 45, -45, 60, -60, 75, -75, 90, -90};
      constexpr std::array<std::array<double, 2>, 13> kChildPoses{{{1.0, 1.0},
                                                                    {1.0, 0.9},
                                                                    {1.0, 0.8},
                                                                    {1.0, 0.7},
                                                                    {1.0, 0.6},
                                                                    {0.85, 1.0},
                                                                    {1.15, 1.0},
                                                                    {0.85, 0.8},
                                                                    {1.15, 0.8},
                                                                    {0.7, 1.0},
                                                                    {1.3, 1.0},
                                                                    {0.7, 0.7},
                                                                    {1.3, 0.7}}};  // {angle factor, length factor}
      const PlannedBranch original_parent = plan[static_cast<std::size_t>(parent_id)];
      bool placed = false;
      std::string first_conflict;
      for (const double extension : kParentExtensions) {
        PlannedBranch& parent = plan[static_cast<std::size_t>(parent_id)];
        parent = original_parent;
        parent.end = parent.start + extension * (original_parent.end - original_parent.start);
        if (extension != 1.0 && conflict_with(parent, parent_id) >= 0) continue;
        const Vec3 u = (parent.end - parent.start).normalized();
        for (const double turn_deg : kTurnsDeg) {
          const Vec3 normal = rotate_about(parent.children_normal, u, turn_deg * kDegToRad);
          const Vec3 w = normal.cross(u).normalized();
          std::array<PlannedBranch, 2> child{};
          std::array<std::size_t, 2> pose{};
          bool both = true;
          for (std::size_t k = 0; k < 2 && both; ++k) {
            const double side = k == 0 ? 1.0 : -1.0;
            bool found = false;
            for (pose[k] = 0; pose[k] < kChildPoses.size(); ++pose[k]) {
              const double a = std::min(angle[k] * kChildPoses[pose[k]][0], kMaxBranchAngle);
              const Vec3 dir = (std::cos(a) * u + side * std::sin(a) * w).normalized();
              child[k].parent = parent_id;
              child[k].generation = generation;
              child[k].radius = 0.5 * diameter[k];
              child[k].blend = p.blend_factor * child[k].radius;
              child[k].start = parent.end;
              child[k].end = parent.end + kChildPoses[pose[k]][1] * length[k] * dir;
              child[k].children_normal = rotate_about(dir.cross(normal).normalized(), dir, child_rotation[k]);
              const int other = conflict_with(child[k], -1);
              if (other < 0) {
                found = true;
                break;
              }
              if (first_conflict.empty()) {
                first_conflict = names[static_cast<std::size_t>(parent_id)] + "-" + std::to_string(k) + " and " +
                                 names[static_cast<std::size_t>(other)];
              }
            }
            both = found;
          }
          if (!both) continue;
          if (extension != 1.0 || turn_deg != 0.0 || pose[0] != 0 || pose[1] != 0) {
            std::string note = "clearance: children of " + names[static_cast<std::size_t>(parent_id)] + ":";
            if (extension != 1.0) note += " parent lengthened x" + format_number(extension) + ";";
            if (turn_deg != 0.0) note += " plane turned " + format_number(turn_deg) + " deg;";
            for (std::size_t k = 0; k < 2; ++k) {
              if (pose[k] == 0) continue;
              note += " child " + std::to_string(k) + " angle x" + format_number(kChildPoses[pose[k]][0]) +
                      ", length x" + format_number(kChildPoses[pose[k]][1]) + ";";
            }
            notes.push_back(note);
          }
          for (std::size_t k = 0; k < 2; ++k) {
            next.push_back(static_cast<int>(plan.size()));
            names.push_back(names[static_cast<std::size_t>(parent_id)] + "-" + std::to_string(k));
            plan.push_back(child[k]);
          }
          placed = true;
          break;
        }
        if (placed) break;
      }
      if (!placed) {
        throw InputError(source_of(kind), 0, "max_generation",
                         "generation " + std::to_string(generation) + ": branches " + first_conflict +
                             " come closer than the clearance (" + format_number(p.clearance / kMmToM) +
                             " mm) in every tried pose (parent lengthened up to x1.5, plane turned up to 90 deg, "
                             "children shortened to 60 % or re-angled); lower max_generation, the jitter or "
                             "clearance_mm");
      }
    }
    frontier = std::move(next);
  }

  // Resolution: the thinnest lumen and the thinnest wall must both span at least two grid cells.
  double min_radius = plan.front().radius;
  for (const PlannedBranch& b : plan) min_radius = std::min(min_radius, b.radius);
  require_spacing(kind, p.spacing, std::min(0.5 * min_radius, p.clearance > 0.0 ? 0.5 * p.clearance : 1e9),
                  "the smallest radius (" + format_number(min_radius / kMmToM) + " mm) and the clearance");

  Phantom phantom;
  const Vec3 entry = Vec3::Zero();
  phantom.mesh = mesh_implicit(field_of(plan, entry), {.spacing = p.spacing});
  phantom.graph = graph_of(plan);
  phantom.meta.kind = kind;
  phantom.meta.seed = p.seed;
  phantom.meta.parameters = {
      {"table", std::string(to_string(p.table))},
      {"max_generation", std::int64_t{p.max_generation}},
      {"flow_ratio", p.flow_ratio},
      {"diameter_exponent", p.diameter_exponent},
      {"length_jitter", p.length_jitter},
      {"angle_jitter_deg", deg(p.angle_jitter)},
      {"rotation_jitter_deg", deg(p.rotation_jitter)},
      {"clearance_mm", p.clearance / kMmToM},
      {"blend_factor", p.blend_factor},
      {"spacing_mm", p.spacing / kMmToM},
  };
  phantom.meta.notes = std::move(notes);
  return phantom;
}

// ---------------------------------------------------------------------------------------------------------------
// Straight tube

Phantom make_tube_phantom(const TubeParams& p) {
  constexpr PhantomKind kind = PhantomKind::kTube;
  require_length(kind, "diameter_mm", p.diameter, 0.5e-3, 100e-3);
  require_length(kind, "length_mm", p.length, p.diameter, 2.0);
  if (p.segments < 8 || p.segments > 4096) {
    throw InputError(source_of(kind), 0, "segments", "must be in [8, 4096] (got " + std::to_string(p.segments) + ")");
  }
  TubeSpec spec;
  spec.radius = 0.5 * p.diameter;
  spec.length = p.length;
  spec.segments = p.segments;
  spec.capped = p.capped;
  Phantom phantom;
  phantom.mesh = make_tube(spec);
  // make_tube runs along +z; the proper rotation (x, y, z) → (z, x, y) lays it along +x.
  for (Vec3& v : phantom.mesh.vertices) v = Vec3(v.z(), v.x(), v.y());
  const double r = spec.radius;
  const std::uint32_t first = add_node(phantom.graph, Vec3(r, 0, 0), r);
  std::vector<std::uint32_t> nodes{first};
  const double span = p.length - 2.0 * r;
  const int segments = subdivisions(span, kGraphNodeSpacing);
  for (int k = 1; k <= segments; ++k) {
    nodes.push_back(add_node(phantom.graph, Vec3(r + span * k / segments, 0, 0), r));
  }
  add_branch(phantom.graph, -1, std::move(nodes));
  phantom.meta.kind = kind;
  phantom.meta.parameters = {{"diameter_mm", p.diameter / kMmToM},
                             {"length_mm", p.length / kMmToM},
                             {"segments", std::int64_t{p.segments}},
                             {"capped", p.capped}};
  phantom.meta.notes = {"parametric tube (make_tube) along +x from x = 0; graph from one radius inside each end",
                        "default 12 mm bore for the thesis's 4-8 mm robots; 120 mm > the 80 mm free length of "
                        "thesis 4.7.1"};
  return phantom;
}

// ---------------------------------------------------------------------------------------------------------------
// Y bifurcation

Phantom make_y_bifurcation(const YBifurcationParams& p) {
  constexpr PhantomKind kind = PhantomKind::kYBifurcation;
  require_length(kind, "parent_diameter_mm", p.parent_diameter, 1e-3, 100e-3);
  require_length(kind, "daughter_diameter_mm", p.daughter_diameter, 1e-3, p.parent_diameter);
  require_length(kind, "parent_length_mm", p.parent_length, 0.5 * p.parent_diameter, 1.0);
  require_length(kind, "daughter_length_mm", p.daughter_length, p.daughter_diameter, 1.0);
  require_range(kind, "branch_angle_deg", p.branch_angle, 10.0 * kDegToRad, 80.0 * kDegToRad, 1.0 / kDegToRad,
                " deg");
  require_range(kind, "blend_factor", p.blend_factor, 0.0, 1.0, 1.0, "");
  require_spacing(kind, p.spacing, 0.25 * p.daughter_diameter, "the daughters (a quarter of their diameter)");

  std::vector<PlannedBranch> plan(3);
  plan[0].radius = 0.5 * p.parent_diameter;
  plan[0].blend = p.blend_factor * 0.5 * p.daughter_diameter;
  plan[0].start = Vec3(plan[0].radius, 0, 0);
  plan[0].end = plan[0].start + Vec3(p.parent_length, 0, 0);
  for (std::size_t k = 1; k <= 2; ++k) {
    const double side = k == 1 ? 1.0 : -1.0;
    plan[k].parent = 0;
    plan[k].generation = 1;
    plan[k].radius = 0.5 * p.daughter_diameter;
    plan[k].blend = p.blend_factor * plan[k].radius;
    plan[k].start = plan[0].end;
    plan[k].end = plan[0].end + p.daughter_length * Vec3(std::cos(p.branch_angle), side * std::sin(p.branch_angle), 0);
  }
  Phantom phantom;
  phantom.mesh = mesh_implicit(field_of(plan, Vec3::Zero()), {.spacing = p.spacing});
  phantom.graph = graph_of(plan);
  phantom.meta.kind = kind;
  phantom.meta.parameters = {{"parent_diameter_mm", p.parent_diameter / kMmToM},
                             {"parent_length_mm", p.parent_length / kMmToM},
                             {"daughter_diameter_mm", p.daughter_diameter / kMmToM},
                             {"daughter_length_mm", p.daughter_length / kMmToM},
                             {"branch_angle_deg", deg(p.branch_angle)},
                             {"blend_factor", p.blend_factor},
                             {"spacing_mm", p.spacing / kMmToM}};
  phantom.meta.notes = {
      "horizontal Y in the x-y plane, entry wall x = 0 one parent radius before the first node; child 0 to +y",
      "defaults: parent 12 mm (Weibel A gen 1: 12.2 mm), daughters 9.5 mm (Hess-Murray 12 * 2^(-1/3)), 35 deg "
      "(Kitaoka symmetric minimum-power angle 34.9 deg; Horsfield 36/35 deg); bench lengths 60/50 mm"};
  return phantom;
}

// ---------------------------------------------------------------------------------------------------------------
// S-bend

Phantom make_s_bend(const SBendParams& p) {
  constexpr PhantomKind kind = PhantomKind::kSBend;
  require_length(kind, "height_mm", p.height, 2e-3, 200e-3);
  require_length(kind, "width_mm", p.width, p.height, 500e-3);
  require_length(kind, "length_mm", p.length, 2.0 * p.width, 2.0);
  require_length(kind, "edge_rounding_mm", p.edge_rounding, 0.0, 0.25 * p.height);
  require_length(kind, "obstacle_thickness_mm", p.obstacle_thickness, 2e-3, 0.25 * p.length);
  // The obstacles must leave a passage at least as high as the channel: reach ≤ width − height.
  require_length(kind, "obstacle_reach_mm", p.obstacle_reach, 0.5 * p.obstacle_thickness, p.width - p.height);
  const double half_t = 0.5 * p.obstacle_thickness;
  const double r_entry = 0.5 * p.height;
  // Obstacles must stay clear of the entry and end nodes' inscribed spheres and of each other.
  require_length(kind, "first_obstacle_x_mm", p.first_obstacle_x, 2.0 * r_entry + half_t, p.length);
  require_length(kind, "second_obstacle_x_mm", p.second_obstacle_x, p.first_obstacle_x + 2.0 * half_t + p.height,
                 p.length - 2.0 * r_entry - half_t);
  require_spacing(kind, p.spacing, 0.125 * p.height, "the channel height (an eighth of it)");

  CompositeSdf field;
  const double rho = p.edge_rounding;
  field.add_lumen(RoundedBox{Vec3(0.5 * p.length, 0, 0), Mat3::Identity(),
                             Vec3(0.5 * p.length - rho, 0.5 * p.width - rho, 0.5 * p.height - rho), rho},
                  0.0);
  // Obstacles: stadium-shaped fins through the full height (rounded box with zero x extent and rounding half_t),
  // from beyond their side wall to their tip at reach from the wall.
  const double beyond = p.height;  // overlap into the wall so the fin is solidly attached
  for (int k = 0; k < 2; ++k) {
    const double side = k == 0 ? -1.0 : 1.0;                 // wall the obstacle grows from
    const double x = k == 0 ? p.first_obstacle_x : p.second_obstacle_x;
    const double wall = side * 0.5 * p.width;
    const double tip = wall - side * p.obstacle_reach;        // y of the tip
    const double core_end = tip + side * half_t;              // the rounded end reaches back out to the tip
    const double core_lo = std::min(wall + side * beyond, core_end);
    const double core_hi = std::max(wall + side * beyond, core_end);
    field.add_obstacle(RoundedBox{Vec3(x, 0.5 * (core_lo + core_hi), 0), Mat3::Identity(),
                                  Vec3(0.0, 0.5 * (core_hi - core_lo), p.height), half_t});
  }

  // Centre line: the entry node, the middle of each passage, the end node; cosine easing between them in y.
  const double y1 = 0.5 * ((-0.5 * p.width + p.obstacle_reach) + 0.5 * p.width);
  const double y2 = -y1;
  const std::array<Vec3, 4> waypoints{Vec3(r_entry, 0, 0), Vec3(p.first_obstacle_x, y1, 0),
                                      Vec3(p.second_obstacle_x, y2, 0), Vec3(p.length - r_entry, 0, 0)};
  Phantom phantom;
  std::vector<std::uint32_t> nodes;
  for (std::size_t s = 0; s + 1 < waypoints.size(); ++s) {
    const Vec3& a = waypoints[s];
    const Vec3& b = waypoints[s + 1];
    const int steps = subdivisions(b.x() - a.x(), kBenchNodeSpacing);
    for (int i = s == 0 ? 0 : 1; i <= steps; ++i) {
      const double t = static_cast<double>(i) / steps;
      const Vec3 q(a.x() + t * (b.x() - a.x()), a.y() + (b.y() - a.y()) * 0.5 * (1.0 - std::cos(kPi * t)), 0.0);
      const double radius = -field.value_at(q);
      if (!(radius > 0.0)) {
        throw InputError(source_of(kind), 0, "obstacle_reach_mm",
                         "the obstacles block the S-shaped path at x = " + format_number(q.x() / kMmToM) + " mm");
      }
      nodes.push_back(add_node(phantom.graph, q, radius));
    }
  }
  add_branch(phantom.graph, -1, std::move(nodes));
  phantom.mesh = mesh_implicit(field, {.spacing = p.spacing});
  phantom.meta.kind = kind;
  phantom.meta.parameters = {{"length_mm", p.length / kMmToM},
                             {"width_mm", p.width / kMmToM},
                             {"height_mm", p.height / kMmToM},
                             {"obstacle_thickness_mm", p.obstacle_thickness / kMmToM},
                             {"obstacle_reach_mm", p.obstacle_reach / kMmToM},
                             {"first_obstacle_x_mm", p.first_obstacle_x / kMmToM},
                             {"second_obstacle_x_mm", p.second_obstacle_x / kMmToM},
                             {"edge_rounding_mm", p.edge_rounding / kMmToM},
                             {"spacing_mm", p.spacing / kMmToM}};
  phantom.meta.notes = {
      "thesis 4.7.3 / fig 4.10 (S-shaped path around two obstacles) gives no dimensions; chosen for its 8 mm robot",
      "channel along +x, entry wall x = 0, floor/ceiling z = -/+ height/2; obstacle 1 from the -y wall, 2 from +y",
      "graph: cosine-eased path through the middle of each passage; node radius = inscribed-sphere radius"};
  return phantom;
}

// ---------------------------------------------------------------------------------------------------------------
// Constriction

Phantom make_constriction(const ConstrictionParams& p) {
  constexpr PhantomKind kind = PhantomKind::kConstriction;
  require_length(kind, "diameter_mm", p.diameter, 2e-3, 100e-3);
  require_length(kind, "length_mm", p.length, 2.0 * p.diameter, 2.0);
  require_length(kind, "jaw_rounding_mm", p.jaw_rounding, 0.0, 0.5 * p.diameter);
  require_length(kind, "constriction_length_mm", p.constriction_length, 2.0 * p.jaw_rounding, p.length);
  const double r = 0.5 * p.diameter;
  require_length(kind, "constriction_x_mm", p.constriction_x, 2.0 * r + 0.5 * p.constriction_length,
                 p.length - 2.0 * r - 0.5 * p.constriction_length);
  if (!(p.gap > 0.0) || !(p.gap < p.diameter)) {
    throw InputError(source_of(kind), 0, "gap_mm",
                     "must be in (0, diameter_mm = " + format_number(p.diameter / kMmToM) + ") (got " +
                         format_number(p.gap / kMmToM) + " mm); the thesis used 2-5 mm");
  }
  require_spacing(kind, p.spacing, 0.25 * p.gap, "the gap (a quarter of it)");

  CompositeSdf field;
  // Cylinder with flat ends: a capsule cut by the planes x = 0 and x = length.
  field.add_lumen(RoundCone{Vec3(-r, 0, 0), Vec3(p.length + r, 0, 0), r, r}, 0.0);
  field.add_clip(Vec3::Zero(), Vec3(-1, 0, 0));
  field.add_clip(Vec3(p.length, 0, 0), Vec3(1, 0, 0));
  // Jaws: rounded boxes whose faces towards the axis are the planes y = ±gap/2.
  const double rho = p.jaw_rounding;
  const double half_depth = r;  // core thickness along y: reaches past the tube wall
  for (const double side : {1.0, -1.0}) {
    field.add_obstacle(RoundedBox{Vec3(p.constriction_x, side * (0.5 * p.gap + rho + half_depth), 0),
                                  Mat3::Identity(), Vec3(0.5 * p.constriction_length - rho, half_depth, r + rho), rho});
  }

  // Centre line along the axis, with a node exactly at the constriction centre.
  std::vector<double> xs;
  const double x0 = r;
  const double x1 = p.length - r;
  const int steps = subdivisions(x1 - x0, kBenchNodeSpacing);
  for (int i = 0; i <= steps; ++i) xs.push_back(x0 + (x1 - x0) * i / steps);
  xs.push_back(p.constriction_x);
  std::sort(xs.begin(), xs.end());
  std::vector<double> kept;
  for (const double x : xs) {
    if (kept.empty() || x - kept.back() > 0.25 * kBenchNodeSpacing) {
      kept.push_back(x);
    } else if (x == p.constriction_x) {
      kept.back() = x;  // keep the exact centre
    }
  }
  Phantom phantom;
  std::vector<std::uint32_t> nodes;
  for (const double x : kept) {
    const Vec3 q(x, 0, 0);
    nodes.push_back(add_node(phantom.graph, q, -field.value_at(q)));
  }
  add_branch(phantom.graph, -1, std::move(nodes));
  phantom.mesh = mesh_implicit(field, {.spacing = p.spacing});
  phantom.meta.kind = kind;
  phantom.meta.parameters = {{"diameter_mm", p.diameter / kMmToM},
                             {"length_mm", p.length / kMmToM},
                             {"gap_mm", p.gap / kMmToM},
                             {"constriction_length_mm", p.constriction_length / kMmToM},
                             {"constriction_x_mm", p.constriction_x / kMmToM},
                             {"jaw_rounding_mm", p.jaw_rounding / kMmToM},
                             {"spacing_mm", p.spacing / kMmToM}};
  phantom.meta.notes = {
      "thesis 5.6.2: vines grown through a 25 mm long gap of variable width (linear actuator); 4.7.2: 5 and 3 mm "
      "passed, 2 mm not, by the 8 mm robot",
      "tube along +x with flat ends at x = 0 and x = length; jaws with flat faces y = +/- gap/2; graph along the axis, "
      "node radius = inscribed-sphere radius (gap/2 in the slot)"};
  return phantom;
}

Phantom make_phantom(const PhantomParams& params) {
  return std::visit(
      [](const auto& p) -> Phantom {
        using T = std::decay_t<decltype(p)>;
        if constexpr (std::is_same_v<T, BronchialTreeParams>) return make_bronchial_tree(p);
        if constexpr (std::is_same_v<T, TubeParams>) return make_tube_phantom(p);
        if constexpr (std::is_same_v<T, YBifurcationParams>) return make_y_bifurcation(p);
        if constexpr (std::is_same_v<T, SBendParams>) return make_s_bend(p);
        if constexpr (std::is_same_v<T, ConstrictionParams>) return make_constriction(p);
      },
      params);
}

// ---------------------------------------------------------------------------------------------------------------
// Files

std::string phantom_metadata_json(const Phantom& phantom) {
  json doc;
  doc["format"] = "magvine-phantom-meta";
  doc["version"] = 1;
  doc["units"] = "mm";
  doc["kind"] = std::string(to_string(phantom.meta.kind));
  doc["seed"] = phantom.meta.seed;
  json params = json::object();
  for (const PhantomParameter& param : phantom.meta.parameters) {
    std::visit([&](const auto& v) { params[param.name] = v; }, param.value);
  }
  doc["parameters"] = std::move(params);
  doc["notes"] = phantom.meta.notes;
  doc["triangles"] = phantom.mesh.triangles.size();
  doc["vertices"] = phantom.mesh.vertices.size();
  doc["branches"] = phantom.graph.branches.size();
  const Aabb box = bounding_box(phantom.mesh);
  const Vec3 lo = box.min / kMmToM;
  const Vec3 hi = box.max / kMmToM;
  doc["bbox_min_mm"] = {lo.x(), lo.y(), lo.z()};
  doc["bbox_max_mm"] = {hi.x(), hi.y(), hi.z()};
  doc["volume_mm3"] = signed_volume(phantom.mesh) / (kMmToM * kMmToM * kMmToM);
  return doc.dump(1) + "\n";
}

std::filesystem::path phantom_graph_path(const std::filesystem::path& stl_path) {
  return stl_path.parent_path() / (stl_path.stem().string() + ".graph.json");
}

std::filesystem::path phantom_meta_path(const std::filesystem::path& stl_path) {
  return stl_path.parent_path() / (stl_path.stem().string() + ".meta.json");
}

void write_phantom(const Phantom& phantom, const std::filesystem::path& stl_path) {
  // The JSON files go to temporary files first and are renamed into place only after the STL succeeded, so a
  // failure leaves no graph or metadata without its mesh.
  AtomicFile graph_file(phantom_graph_path(stl_path));
  graph_file.stream() << graph_to_json(phantom.graph);
  AtomicFile meta_file(phantom_meta_path(stl_path));
  meta_file.stream() << phantom_metadata_json(phantom);
  write_stl(stl_path, phantom.mesh, LengthUnit::kMm);
  graph_file.commit();
  meta_file.commit();
}

}  // namespace magvine::anatomy
