#include "magvine/anatomy/biopsy_plan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <vector>

#include "magvine/core/text.hpp"

namespace magvine::anatomy {

namespace {

/// Direction of branch b at its k-th node (central difference along the polyline).
Vec3 tangent_at(const AirwayGraph& graph, const AirwayBranch& b, std::size_t k) {
  const std::size_t lo = k > 0 ? k - 1 : 0, hi = std::min(k + 1, b.nodes.size() - 1);
  return (graph.nodes[b.nodes[hi]].position - graph.nodes[b.nodes[lo]].position).normalized();
}

}  // namespace

double straight_miss(const Vec3& start, const Vec3& direction, const Vec3& point) {
  const Vec3 d = point - start;
  const double along = d.dot(direction);
  return along <= 0.0 ? d.norm() : (d - along * direction).norm();
}

BiopsyPlan plan_biopsy(const AirwayGraph& graph, const CollisionWorld& world, const Vec3& nodule,
                       const BiopsyOptions& options) {
  BiopsyPlan plan;
  std::vector<BiopsyPlan> candidates;  // every stop that passes the rules, in graph order
  // A given stop: the reachable node nearest to it, taken whatever the rules say (evaluated after the walk).
  const AirwayBranch* given_branch = nullptr;
  std::size_t given_k = 0;
  double given_distance = std::numeric_limits<double>::infinity();
  // Branches the tool fits into: their parent fits and every node is wide enough (a branch's first node is its
  // parent's last, already checked).
  std::vector<char> fits(graph.branches.size(), 0);
  // The plan for a stop at node k of branch b whose needle leaves the airway at `exit` on its way to the nodule.
  const auto stop_at = [&](const AirwayBranch& b, std::size_t k, const RayHit& exit) {
    const AirwayNode& node = graph.nodes[b.nodes[k]];
    const Vec3 d = nodule - node.position;
    const Vec3 dir = d.normalized();
    const Vec3 along = tangent_at(graph, b, k);
    BiopsyPlan c;
    c.found = true;
    c.node = b.nodes[k];
    c.branch = b.id;
    c.start = node.position;
    c.wall = exit.point;
    c.direction = dir;
    c.needle = d.norm() - exit.distance;
    c.angle = std::acos(std::clamp(dir.dot(along), -1.0, 1.0));
    c.straight_miss = straight_miss(node.position, along, nodule);
    c.lumen_radius = node.radius;
    return c;
  };
  for (const AirwayBranch& b : graph.branches) {  // parents come before their children (add_branch order)
    if (b.parent >= 0 && !fits[static_cast<std::size_t>(b.parent)]) continue;
    for (std::size_t k = 0; k < b.nodes.size(); ++k) {
      const std::uint32_t n = b.nodes[k];
      const AirwayNode& node = graph.nodes[n];
      if (node.radius < options.tool_radius) break;  // the tool stops here: the rest of the branch is out of reach
      if (k + 1 == b.nodes.size()) fits[static_cast<std::size_t>(b.id)] = 1;
      if (b.parent >= 0 && k == 0) continue;  // the parent's end node, already a candidate
      ++plan.reachable;
      if (options.stop && (node.position - *options.stop).norm() < given_distance) {
        given_distance = (node.position - *options.stop).norm();
        given_branch = &b;
        given_k = k;
      }
      const Vec3 d = nodule - node.position;
      const double length = d.norm();
      if (!(length > 0.0)) continue;
      const Vec3 dir = d / length;
      // The robot arrives from the root, so the tip points along the branch's direction of growth.
      const Vec3 along = tangent_at(graph, b, k);
      const double forward = std::acos(std::clamp(dir.dot(along), -1.0, 1.0));
      const double miss = straight_miss(node.position, along, nodule);
      if (miss < plan.best_straight_miss) {
        plan.best_straight_miss = miss;
        plan.best_straight_branch = b.id;
      }
      if (options.stop) continue;  // the given stop is the only candidate
      if (forward > options.max_angle) {
        ++plan.too_steep;
        continue;
      }
      const auto exit = world.ray_cast(node.position, dir, length);
      if (!exit) continue;  // the nodule lies inside the lumen from here: not a biopsy target
      const double needle = length - exit->distance;
      if (needle > options.max_needle) {
        ++plan.too_long;
        continue;
      }
      const Vec3 beyond = exit->point + 1e-6 * dir;
      if (world.segment_crosses(beyond, nodule)) {
        ++plan.through_airway;
        continue;
      }
      candidates.push_back(stop_at(b, k, *exit));
    }
  }
  if (options.stop) {
    if (given_branch == nullptr) {
      plan.why =
          printf_string("no centreline node is reachable by a tool of radius %.1f mm", 1e3 * options.tool_radius);
      return plan;
    }
    const Vec3 from = graph.nodes[given_branch->nodes[given_k]].position;
    const Vec3 d = nodule - from;
    const auto exit = d.norm() > 0.0 ? world.ray_cast(from, d.normalized(), d.norm()) : std::nullopt;
    if (!exit) {
      plan.why = printf_string(
          "the given stop's nearest reachable node (branch %s, %.1f mm from it) sees the nodule inside the lumen: "
          "no wall to pass",
          given_branch->name.c_str(), 1e3 * given_distance);
      return plan;
    }
    const BiopsyPlan counts = plan;
    plan = stop_at(*given_branch, given_k, *exit);
    plan.reachable = counts.reachable;
    plan.best_straight_miss = counts.best_straight_miss;
    plan.best_straight_branch = counts.best_straight_branch;
    plan.given_distance = given_distance;
    plan.crosses_airway = world.segment_crosses(exit->point + 1e-6 * plan.direction, nodule);
    return plan;
  }
  // The shortest needle, and of those within needle_tolerance of it the one the tip needs to turn least for
  // (then the shorter needle, then the first in graph order).
  double shortest = std::numeric_limits<double>::infinity();
  for (const BiopsyPlan& c : candidates) shortest = std::min(shortest, c.needle);
  const BiopsyPlan* best = nullptr;
  for (const BiopsyPlan& c : candidates) {
    if (c.needle > shortest + options.needle_tolerance) continue;
    if (best == nullptr || c.angle < best->angle || (c.angle == best->angle && c.needle < best->needle)) best = &c;
  }
  if (best != nullptr) {
    const BiopsyPlan counts = plan;
    plan = *best;
    plan.reachable = counts.reachable;
    plan.too_long = counts.too_long;
    plan.too_steep = counts.too_steep;
    plan.through_airway = counts.through_airway;
    plan.best_straight_miss = counts.best_straight_miss;
    plan.best_straight_branch = counts.best_straight_branch;
  }
  if (!plan.found) {
    std::ostringstream s;
    s << "no stop reaches the nodule: " << plan.reachable << " centreline nodes reachable by a tool of radius "
      << 1e3 * options.tool_radius << " mm; " << plan.too_steep << " would turn the needle more than "
      << options.max_angle * 180.0 / std::numbers::pi << " deg from the branch, " << plan.too_long << " need more than "
      << 1e3 * options.max_needle << " mm of needle, " << plan.through_airway << " would cross another airway";
    if (plan.best_straight_branch >= 0) {
      s << " (a tip pointing along its branch passes the nodule's centre at "
        << printf_string("%.1f", 1e3 * plan.best_straight_miss) << " mm at best, in branch "
        << graph.branches[static_cast<std::size_t>(plan.best_straight_branch)].name << ")";
    }
    plan.why = s.str();
  }
  return plan;
}

}  // namespace magvine::anatomy
