#pragma once
/// Where to stop the robot's tip for a transbronchial needle biopsy of a nodule outside the airway (issue 31, item 2):
/// the centreline point from which a straight needle, pushed out of the tip, reaches the nodule along the shortest
/// path through tissue without entering another airway, in a branch the robot fits all the way in.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/collision_world.hpp"

namespace magvine::anatomy {

struct BiopsyOptions {
  double tool_radius = 2.5e-3;  ///< the robot's radius: every node on the way must be at least this wide [m]
  double max_needle = 0.05;     ///< longest needle path through tissue, wall to nodule centre [m]
  /// Largest angle between the needle and the branch's direction at the stop: the tip turns this far towards the
  /// wall before the needle leaves it (the tool channel leaves along the tip). [rad]
  double max_angle = 1.0471975511965976;  // 60°
  /// Needle paths within this of the shortest count as equally short; of those the stop whose branch points most
  /// nearly at the nodule wins (the needle leaves along the tip: the less it must be turned, the better) [m]. 1 mm:
  /// two voxels of a CT segmentation, below what the surface's placement resolves.
  double needle_tolerance = 1e-3;
  /// A given stop (e.g. a planning problem's start pose on the bronchial wall) [m]: the node the tool fits to
  /// nearest it is the stop, taken as given: its needle, angle and whether it crosses another airway are reported,
  /// max_needle and max_angle are not applied (refused only where the nodule lies inside the lumen from there).
  std::optional<Vec3> stop = std::nullopt;
};

/// The chosen stop and needle path.
struct BiopsyPlan {
  bool found = false;
  std::uint32_t node = 0;          ///< the stop: a centreline node
  int branch = -1;                 ///< its branch
  Vec3 start = Vec3::Zero();       ///< the node's position: where the tip stops [m]
  Vec3 wall = Vec3::Zero();        ///< where the needle leaves the airway [m]
  Vec3 direction = Vec3::UnitX();  ///< unit, start → nodule centre
  double needle = 0.0;             ///< needle path in tissue, wall → nodule centre [m]
  double angle = 0.0;              ///< needle against the branch's direction [rad]
  double lumen_radius = 0.0;       ///< the node's radius [m]
  /// A tip that cannot turn (a tool as wide as its lumen) points along its branch: how far that ray from the stop
  /// passes from the nodule's centre [m] (`straight_miss`, below).
  double straight_miss = 0.0;
  /// The smallest straight_miss over every node the tool fits to, whatever the needle's length or angle, and that
  /// node's branch: no tip that cannot turn gets its needle closer to the nodule's centre than this [m].
  double best_straight_miss = std::numeric_limits<double>::infinity();
  int best_straight_branch = -1;
  double given_distance = 0.0;  ///< with a given stop: from it to the node taken [m]
  bool crosses_airway = false;  ///< with a given stop: its needle passes through another airway on the way
  std::size_t reachable = 0;    ///< nodes the tool fits to
  std::size_t too_long = 0, too_steep = 0, through_airway = 0;  ///< reachable nodes ruled out, by reason
  std::string why;                                              ///< when none is found: the reasons, counted
};

/// How far the ray from `start` along the unit `direction` passes from `point`: the distance to the ray's nearest
/// point (its start when the point lies behind it) [m]. A needle pushed `direction`-wards from `start` ends no
/// nearer the point than this, whatever its length.
double straight_miss(const Vec3& start, const Vec3& direction, const Vec3& point);

/// Plans the stop for a nodule centred at `nodule` [m] (outside the lumen). Candidates are the graph's nodes reached
/// from the root through nodes at least `tool_radius` wide; for each, the needle runs from the node straight to the
/// nodule centre: the first wall crossing (ray cast) is where it leaves the airway, and a second crossing before the
/// nodule would take it through another airway (ruled out). Among those within max_needle and max_angle, of the
/// needle paths within needle_tolerance of the shortest the smallest angle wins (then the shorter needle, then the
/// first node in graph order). With options.stop, that stop's nearest reachable node instead (BiopsyOptions::stop).
BiopsyPlan plan_biopsy(const AirwayGraph& graph, const CollisionWorld& world, const Vec3& nodule,
                       const BiopsyOptions& options = {});

}  // namespace magvine::anatomy
