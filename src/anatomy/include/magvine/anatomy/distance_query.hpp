#pragma once
/// "How far is the wall": exact Euclidean distances from points and capsules to an anatomy mesh (lumen radius, tissue
/// proximity). Built once from a TriangleMesh into an FCL bounding-volume hierarchy; queries are const and use a
/// caller-owned DistanceWorkspace. Robot contact forces do not go through here (they use the collision world).
///
/// Distances are unsigned: this class does not know which side of the wall is lumen, so a point in tissue at 1 mm
/// from the wall also reports 1 mm.

#include <cstdint>
#include <memory>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// Bounding volume of the FCL hierarchy.
enum class DistanceBv {
  kAabb,    ///< axis-aligned boxes: the fastest measured with the direct traversal (the default)
  kRss,     ///< rectangle swept spheres: tighter, fewer nodes visited, but 2.1× the node size; ~40 % slower
  kObbRss,  ///< FCL's OBB+RSS pair (the direct traversal uses the RSS half); mainly for `DistanceTraversal::kFcl`
};

/// How FCL splits a node while building the hierarchy (fcl::detail::SplitMethodType).
enum class DistanceSplit {
  kMean,      ///< split at the mean of the triangle centroids along the longest axis (FCL's default)
  kMedian,    ///< split at the median centroid
  kBvCenter,  ///< split at the centre of the node's bounding volume (on lidc0525: fine for AABB, but RSS trees
              ///< twice as deep and 4× slower to query)
};

/// Which code walks the hierarchy.
enum class DistanceTraversal {
  /// magvine's own depth-first branch-and-bound over FCL's nodes (nearer child first) with exact point– and
  /// segment–triangle leaf tests. The default: ~6× faster than kFcl for points, and exact for segments.
  kDirect,
  /// fcl::distance() with an fcl::Sphere of radius 0 for points (FCL's exact sphere–triangle leaf: agrees with
  /// kDirect to round-off, ~6× slower) and an fcl::Capsule of radius 0 for segments (FCL's GJK, GST_INDEP: NOT
  /// exact — on the real airway it misses ~1.4 % of wall crossings and errs by up to ~40 µm elsewhere, see
  /// distance_query.cpp). Needs kRss or kObbRss. Kept as an independent reference for tests and benchmarks.
  /// Caveats of FCL 0.7: each query allocates twice inside FCL (computeBV of the shape builds a std::vector); a
  /// segment touching the wall comes back as a collision without points, so on_segment/on_mesh are NaN; a point
  /// exactly on the surface (squared distance exactly 0) makes FCL read an uninitialised distance.
  kFcl,
};

/// How to build a DistanceQuery.
struct DistanceQueryOptions {
  DistanceBv bv = DistanceBv::kAabb;                         ///< bounding volume of the hierarchy
  DistanceSplit split = DistanceSplit::kMean;                ///< how FCL splits nodes while building
  DistanceTraversal traversal = DistanceTraversal::kDirect;  ///< who walks the hierarchy
};

/// Nearest point on the mesh to a query point.
struct PointDistance {
  double distance = 0.0;         ///< Euclidean distance from the point to the mesh surface [m], ≥ 0
  Vec3 nearest = Vec3::Zero();   ///< closest point on the mesh, world frame [m]
  std::int64_t triangle = -1;    ///< index into TriangleMesh::triangles of a triangle containing `nearest`
                                 ///< (where several points are equally near, which one is reported depends on the
                                 ///< traversal order and the warm start; the distance does not)
};

/// Distance from a capsule (segment a–b swept by a ball of radius r) to the mesh.
///
/// The segment-to-mesh distance s is computed exactly (DistanceTraversal::kDirect); everything else follows from it:
///   distance = s − r  (signed clearance). > 0: gap to the wall. < 0: the capsule overlaps the wall and
///   −distance = r − s is the overlap depth along the nearest direction (`on_mesh` − `on_segment`), i.e. a local
///   penetration estimate. While the axis stays off the wall (s > 0) it is the depth of that contact; once the
///   axis touches or crosses the wall (s = 0, `axis_crosses_wall`) the depth is only known to be ≥ r and
///   distance = −r.
struct CapsuleDistance {
  double distance = 0.0;            ///< signed clearance s − r [m]; see above
  double axis_distance = 0.0;       ///< s: distance from the segment a–b to the mesh [m], ≥ 0
  bool intersects = false;          ///< the capsule overlaps the wall: s < r
  bool axis_crosses_wall = false;   ///< the segment itself touches or crosses the wall: s = 0
  Vec3 on_segment = Vec3::Zero();   ///< closest point on the segment a–b, world frame [m]
  Vec3 on_capsule = Vec3::Zero();   ///< on_segment + r·unit(on_mesh − on_segment): the capsule's surface point
                                    ///< nearest the wall (inside tissue when intersecting); = on_segment if s = 0
  Vec3 on_mesh = Vec3::Zero();      ///< closest point on the mesh, world frame [m]
  std::int64_t triangle = -1;       ///< index into TriangleMesh::triangles of a triangle containing `on_mesh`
};

class DistanceQuery;

namespace detail {
/// One entry of DistanceWorkspace's traversal stack (implementation detail of DistanceQuery).
struct DistanceStackEntry {
  double bound_sq = 0.0;    ///< squared lower bound of the distance to the node's triangles [m²]
  std::int32_t node = 0;    ///< FCL node index
};
}  // namespace detail

/// Per-thread scratch for DistanceQuery: the traversal stack and the previous query's nearest triangle. Sized on
/// first use with a query (one allocation); later queries with the same DistanceQuery do not allocate. Give each
/// thread its own workspace.
class DistanceWorkspace {
 public:
  /// Seed each query with the previous query's nearest triangle as the initial upper bound (FCL's own traversal
  /// starts from triangle 0). Does not change results, only speed: it helps spatially coherent queries (successive
  /// robot nodes) and costs one triangle test otherwise.
  bool warm_start = true;

 private:
  friend class DistanceQuery;
  std::vector<detail::DistanceStackEntry> m_stack;
  std::int64_t m_hint = -1;           // previous nearest triangle, -1 = none
  const void* m_owner = nullptr;      // the DistanceQuery implementation the stack and hint belong to
};

/// FCL bounding-volume hierarchy over a triangle mesh, answering exact distance queries. Immutable after
/// construction. Thread-safety: all queries are const and read only immutable data plus the workspace passed in,
/// so any number of threads may query one object concurrently, each with its own DistanceWorkspace (this also
/// holds for DistanceTraversal::kFcl: fcl::distance keeps no shared mutable state besides its function-local
/// static dispatch table, initialised thread-safely).
class DistanceQuery {
 public:
  /// Builds the hierarchy (copies the mesh into FCL). Throws InputError for a mesh without triangles, a non-finite
  /// vertex or a triangle index out of range; std::invalid_argument for kFcl with kAabb (FCL 0.7 has no
  /// mesh–shape distance for AABB trees). Zero-area triangles are accepted (the leaf tests handle them).
  explicit DistanceQuery(const TriangleMesh& mesh, const DistanceQueryOptions& options = {});
  ~DistanceQuery();
  /// Movable (a moved-from query may only be destroyed or assigned to); not copyable.
  DistanceQuery(DistanceQuery&&) noexcept;
  DistanceQuery& operator=(DistanceQuery&&) noexcept;
  DistanceQuery(const DistanceQuery&) = delete;
  DistanceQuery& operator=(const DistanceQuery&) = delete;

  /// Closest point on the mesh to `point` (world frame [m]). Exact up to round-off.
  PointDistance nearest_point(const Vec3& point, DistanceWorkspace& workspace) const;

  /// Distance from the capsule with axis a–b (world frame [m]) and `radius` [m] (≥ 0) to the mesh. a = b is a
  /// sphere; radius 0 is a segment. Exact up to round-off with kDirect (kFcl: GJK, see DistanceTraversal).
  CapsuleDistance capsule_distance(const Vec3& a, const Vec3& b, double radius, DistanceWorkspace& workspace) const;

  /// Radius of the largest ball centred at `point` that touches no wall [m]: the local lumen radius when `point`
  /// is on the airway centreline, the clearance to the nearest wall otherwise. Same as nearest_point().distance.
  double lumen_radius(const Vec3& point, DistanceWorkspace& workspace) const;

  /// A workspace already sized for this query (so that even the first query does not allocate).
  DistanceWorkspace make_workspace() const;

  std::size_t num_triangles() const;        ///< triangles in the hierarchy
  int tree_depth() const;                   ///< edges on the longest root-to-leaf path of the hierarchy
  const DistanceQueryOptions& options() const;  ///< the options it was built with

 private:
  struct Impl;
  void prepare(DistanceWorkspace& workspace) const;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace magvine::anatomy
