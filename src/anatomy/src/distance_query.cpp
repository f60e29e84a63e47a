#include "magvine/anatomy/distance_query.hpp"
#include "magvine/core/usage.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/bvh/detail/BV_splitter.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/math/bv/RSS.h>
#include <fcl/narrowphase/distance.h>

#include "magvine/anatomy/segment_geometry.hpp"
#include "magvine/core/check.hpp"
#include "magvine/core/error.hpp"

namespace magvine::anatomy {
namespace {

using StackEntry = detail::DistanceStackEntry;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------------------------
// Exact closest-point primitives.
// ---------------------------------------------------------------------------------------------------------------

/// Closest points c1 on p1–q1 and c2 on p2–q2 (segment_geometry.hpp).
void closest_segment_segment(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2, Vec3& c1, Vec3& c2) {
  const SegmentParameters c = closest_segment_parameters(p1, q1 - p1, p2, q2 - p2);
  c1 = p1 + (q1 - p1) * c.s;
  c2 = p2 + (q2 - p2) * c.t;
}

/// Squared distance between the segment a–b and triangle p0 p1 p2, with the closest points. If the segment
/// crosses the triangle the distance is 0 at the crossing point. Otherwise the minimum is attained with a segment
/// endpoint or a triangle edge in the pair (an interior–interior minimum needs the segment parallel to the plane,
/// and then sliding along it reaches an endpoint or an edge at the same distance).
double segment_triangle_sq(const Vec3& a, const Vec3& b, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                           Vec3& on_segment, Vec3& on_triangle) {
  const Vec3 n = (p1 - p0).cross(p2 - p0);
  const double da = n.dot(a - p0), db = n.dot(b - p0);
  if (((da <= 0.0 && db >= 0.0) || (da >= 0.0 && db <= 0.0)) && da != db) {
    const Vec3 x = a + (b - a) * (da / (da - db));  // where the segment meets the triangle's plane
    if (n.dot((p1 - p0).cross(x - p0)) >= 0.0 && n.dot((p2 - p1).cross(x - p1)) >= 0.0 &&
        n.dot((p0 - p2).cross(x - p2)) >= 0.0) {
      on_segment = on_triangle = x;
      return 0.0;
    }
  }
  double best = kInf;
  const Vec3* corners[3] = {&p0, &p1, &p2};
  for (int i = 0; i < 3; ++i) {
    Vec3 u, w;
    closest_segment_segment(a, b, *corners[i], *corners[(i + 1) % 3], u, w);
    const double d = (u - w).squaredNorm();
    if (d < best) {
      best = d;
      on_segment = u;
      on_triangle = w;
    }
  }
  for (const Vec3* e : {&a, &b}) {
    const Vec3 c = closest_point_on_triangle(*e, p0, p1, p2);
    const double d = (c - *e).squaredNorm();
    if (d < best) {
      best = d;
      on_segment = *e;
      on_triangle = c;
    }
  }
  return best;
}

// ---------------------------------------------------------------------------------------------------------------
// Lower bounds of the distance from a query to a bounding volume, squared [m²]. Zero when the query touches it.
// ---------------------------------------------------------------------------------------------------------------

double point_bound_sq(const fcl::AABBd& box, const Vec3& p) {
  return (box.min_ - p).cwiseMax(p - box.max_).cwiseMax(0.0).squaredNorm();
}

/// RSS = rectangle To + [0, l0]·axis₀ + [0, l1]·axis₁ swept by a ball of radius r.
double point_bound_sq(const fcl::RSSd& rss, const Vec3& p) {
  const Vec3 q = rss.axis.transpose() * (p - rss.To);  // rectangle frame
  const double x = q[0] - std::clamp(q[0], 0.0, rss.l[0]);
  const double y = q[1] - std::clamp(q[1], 0.0, rss.l[1]);
  const double d = std::max(std::sqrt(x * x + y * y + q[2] * q[2]) - rss.r, 0.0);
  return d * d;
}

double point_bound_sq(const fcl::OBBRSSd& bv, const Vec3& p) { return point_bound_sq(bv.rss, p); }

/// A query segment x(t) = a + t·d, t ∈ [0, 1], and the same segment as a zero-radius RSS for FCL's RSS distance.
struct Segment {
  Vec3 a;
  Vec3 d;
  fcl::RSSd rss;
};

Segment make_segment(const Vec3& a, const Vec3& b) {
  Segment s{a, b - a, fcl::RSSd()};
  const double length = s.d.norm();
  s.rss.To = a;
  s.rss.l[0] = length;
  s.rss.l[1] = 0.0;
  s.rss.r = 0.0;
  if (length > 0.0) {
    const Vec3 e0 = s.d / length, e1 = e0.unitOrthogonal();
    s.rss.axis.col(0) = e0;
    s.rss.axis.col(1) = e1;
    s.rss.axis.col(2) = e0.cross(e1);
  } else {
    s.rss.axis.setIdentity();
  }
  return s;
}

/// Exact squared distance from the segment to the box. f(t) = |x(t) − clamp(x(t), lo, hi)|² is convex and C¹ with
/// f'(t) = 2 Σᵢ dᵢ·eᵢ(t), eᵢ the excess of xᵢ over [loᵢ, hiᵢ]; f' is linear between the ≤ 6 parameters where some
/// xᵢ(t) crosses loᵢ or hiᵢ. Bracket the root of f' with those breakpoints and interpolate linearly.
double segment_bound_sq(const fcl::AABBd& box, const Segment& s) {
  const Vec3& lo = box.min_;
  const Vec3& hi = box.max_;
  const auto excess = [&](double t, int i) {
    const double x = s.a[i] + t * s.d[i];
    return x < lo[i] ? x - lo[i] : (x > hi[i] ? x - hi[i] : 0.0);
  };
  const auto slope = [&](double t) { return s.d[0] * excess(t, 0) + s.d[1] * excess(t, 1) + s.d[2] * excess(t, 2); };
  const auto value = [&](double t) {
    const double e0 = excess(t, 0), e1 = excess(t, 1), e2 = excess(t, 2);
    return e0 * e0 + e1 * e1 + e2 * e2;
  };
  double t0 = 0.0, g0 = slope(0.0);
  if (g0 >= 0.0) return value(0.0);
  double t1 = 1.0, g1 = slope(1.0);
  if (g1 <= 0.0) return value(1.0);
  for (int i = 0; i < 3; ++i) {
    if (s.d[i] == 0.0) continue;
    for (const double bound : {lo[i], hi[i]}) {
      const double t = (bound - s.a[i]) / s.d[i];
      if (!(t > t0 && t < t1)) continue;
      const double g = slope(t);
      if (g < 0.0) {
        t0 = t;
        g0 = g;
      } else if (g > 0.0) {
        t1 = t;
        g1 = g;
      } else {
        return value(t);
      }
    }
  }
  return value(t0 + (t1 - t0) * (g0 / (g0 - g1)));
}

/// FCL's exact rectangle–rectangle distance (the segment is a rectangle of width 0), minus the node's radius.
double segment_bound_sq(const fcl::RSSd& rss, const Segment& s) {
  const double d = fcl::distance(fcl::Matrix3d::Identity(), fcl::Vector3d::Zero(), s.rss, rss);
  return d * d;
}

double segment_bound_sq(const fcl::OBBRSSd& bv, const Segment& s) { return segment_bound_sq(bv.rss, s); }

// ---------------------------------------------------------------------------------------------------------------
// The hierarchy and its traversals.
// ---------------------------------------------------------------------------------------------------------------

/// The workspace parts a traversal uses.
struct Scratch {
  std::vector<StackEntry>& stack;
  std::int64_t& hint;
  bool warm_start;
};

/// Result of a segment query before the capsule radius is applied.
struct SegmentHit {
  double distance_sq = kInf;
  Vec3 on_segment = Vec3::Zero();
  Vec3 on_mesh = Vec3::Zero();
  std::int64_t triangle = -1;
};

class Tree {
 public:
  virtual ~Tree() = default;
  virtual PointDistance nearest_point(const Vec3& p, const Scratch& scratch) const = 0;
  virtual SegmentHit nearest_to_segment(const Vec3& a, const Vec3& b, const Scratch& scratch) const = 0;
  virtual std::size_t num_triangles() const = 0;
  virtual int depth() const = 0;
};

fcl::detail::SplitMethodType fcl_split(DistanceSplit split) {
  switch (split) {
    case DistanceSplit::kMean: return fcl::detail::SPLIT_METHOD_MEAN;
    case DistanceSplit::kMedian: return fcl::detail::SPLIT_METHOD_MEDIAN;
    case DistanceSplit::kBvCenter: return fcl::detail::SPLIT_METHOD_BV_CENTER;
  }
  return fcl::detail::SPLIT_METHOD_MEAN;
}

template <class BV>
class BvhTree final : public Tree {
 public:
  BvhTree(const TriangleMesh& mesh, const DistanceQueryOptions& options)
      : m_triangles(mesh.triangles), m_traversal(options.traversal) {
    std::vector<fcl::Triangle> triangles;
    triangles.reserve(mesh.triangles.size());
    for (const Triangle& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
    m_model.bv_splitter = std::make_shared<fcl::detail::BVSplitter<BV>>(fcl_split(options.split));
    if (m_model.beginModel(static_cast<int>(triangles.size()), static_cast<int>(mesh.vertices.size())) != fcl::BVH_OK ||
        m_model.addSubModel(mesh.vertices, triangles) != fcl::BVH_OK || m_model.endModel() != fcl::BVH_OK) {
      throw std::runtime_error("DistanceQuery: FCL could not build the bounding-volume hierarchy");
    }
    m_depth = compute_depth();
  }

  std::size_t num_triangles() const override { return static_cast<std::size_t>(m_model.num_tris); }
  int depth() const override { return m_depth; }

  PointDistance nearest_point(const Vec3& p, const Scratch& scratch) const override {
    return m_traversal == DistanceTraversal::kFcl ? nearest_point_fcl(p, scratch) : nearest_point_direct(p, scratch);
  }

  SegmentHit nearest_to_segment(const Vec3& a, const Vec3& b, const Scratch& scratch) const override {
    return m_traversal == DistanceTraversal::kFcl ? segment_fcl(a, b, scratch) : segment_direct(a, b, scratch);
  }

 private:
  /// Corner k of triangle t. The indices come from our own copy (12 B per triangle): fcl::Triangle's operator[] is
  /// an out-of-line call into libfcl.so, three per leaf test.
  const Vec3& vertex(std::int64_t t, int k) const {
    return m_model.vertices[m_triangles[static_cast<std::size_t>(t)][static_cast<std::size_t>(k)]];
  }

  /// Longest root-to-leaf path (in edges).
  int compute_depth() const {
    int deepest = 0;
    std::vector<std::pair<int, int>> todo{{0, 0}};
    while (!todo.empty()) {
      const auto [node, level] = todo.back();
      todo.pop_back();
      deepest = std::max(deepest, level);
      const int first_child = m_model.getBV(node).first_child;
      if (first_child < 0) continue;
      todo.emplace_back(first_child, level + 1);
      todo.emplace_back(first_child + 1, level + 1);
    }
    return deepest;
  }

  /// Depth-first branch and bound over FCL's nodes, nearer child first. `bound(bv)` is a squared lower bound of the
  /// distance to everything in a node; `leaf(triangle)` tests one triangle and lowers `best_sq`. A node is skipped
  /// once its bound reaches `best_sq`, so the result is exact (up to round-off in the bounds). The stack holds at
  /// most one sibling per level, so depth + 1 entries suffice.
  template <class Bound, class Leaf>
  void traverse(std::vector<StackEntry>& stack, const double& best_sq, const Bound& bound, const Leaf& leaf) const {
    std::size_t top = 0;
    stack[top++] = {0.0, 0};
    while (top > 0) {
      const StackEntry entry = stack[--top];
      if (entry.bound_sq >= best_sq) continue;
      int node = entry.node;
      for (;;) {
        // FCL's node layout (BVNodeBase): first_child ≥ 0 is the left child, the right one follows it;
        // first_child < 0 marks a leaf holding triangle −(first_child + 1). Read directly: FCL's accessors
        // (isLeaf, primitiveId, ...) are out-of-line calls into libfcl.so.
        const int first_child = m_model.getBV(node).first_child;
        if (first_child < 0) {
          leaf(static_cast<std::int64_t>(-(first_child + 1)));
          break;
        }
        int near = first_child, far = first_child + 1;
        double near_sq = bound(m_model.getBV(near).bv), far_sq = bound(m_model.getBV(far).bv);
        if (far_sq < near_sq) {
          std::swap(near, far);
          std::swap(near_sq, far_sq);
        }
        if (near_sq >= best_sq) break;
        if (far_sq < best_sq) {
          MAGVINE_ASSERT(top < stack.size());
          stack[top++] = {far_sq, static_cast<std::int32_t>(far)};
        }
        node = near;
      }
    }
  }

  std::int64_t usable_hint(const Scratch& scratch) const {
    const std::int64_t h = scratch.hint;
    return scratch.warm_start && h >= 0 && h < m_model.num_tris ? h : -1;
  }

  PointDistance nearest_point_direct(const Vec3& p, const Scratch& scratch) const {
    double best_sq = kInf;
    PointDistance out;
    const auto leaf = [&](std::int64_t t) {
      const Vec3 c = closest_point_on_triangle(p, vertex(t, 0), vertex(t, 1), vertex(t, 2));
      const double d = (c - p).squaredNorm();
      if (d < best_sq) {
        best_sq = d;
        out.nearest = c;
        out.triangle = t;
      }
    };
    if (const std::int64_t h = usable_hint(scratch); h >= 0) leaf(h);
    traverse(scratch.stack, best_sq, [&](const BV& bv) { return point_bound_sq(bv, p); }, leaf);
    out.distance = std::sqrt(best_sq);
    scratch.hint = out.triangle;
    return out;
  }

  SegmentHit segment_direct(const Vec3& a, const Vec3& b, const Scratch& scratch) const {
    const Segment segment = make_segment(a, b);
    SegmentHit out;
    const auto leaf = [&](std::int64_t t) {
      Vec3 on_segment, on_mesh;
      const double d = segment_triangle_sq(a, b, vertex(t, 0), vertex(t, 1), vertex(t, 2), on_segment, on_mesh);
      if (d < out.distance_sq) {
        out = {d, on_segment, on_mesh, t};
      }
    };
    if (const std::int64_t h = usable_hint(scratch); h >= 0) leaf(h);
    traverse(scratch.stack, out.distance_sq, [&](const BV& bv) { return segment_bound_sq(bv, segment); }, leaf);
    scratch.hint = out.triangle;
    return out;
  }

  /// fcl::distance with a radius-0 sphere: FCL 0.7 accepts it and its sphere–triangle leaf (Project::projectTriangle)
  /// is exact. A tiny positive radius is worse: FCL treats the ball as colliding within that radius and then reports
  /// an uninitialised distance. The warm-start triangle pre-fills the result, which FCL's traversal only lowers.
  PointDistance nearest_point_fcl(const Vec3& p, const Scratch& scratch) const {
    const fcl::Sphered point(0.0);
    fcl::Transform3d pose = fcl::Transform3d::Identity();
    pose.translation() = p;
    const fcl::DistanceRequestd request(true);  // nearest points; rel_err = abs_err = 0: exact traversal
    fcl::DistanceResultd result;
    if (const std::int64_t h = usable_hint(scratch); h >= 0) {
      const Vec3 c = closest_point_on_triangle(p, vertex(h, 0), vertex(h, 1), vertex(h, 2));
      result.update((c - p).norm(), &m_model, &point, static_cast<int>(h), fcl::DistanceResultd::NONE, c, p);
    }
    fcl::distance(&m_model, fcl::Transform3d::Identity(), &point, pose, request, result);
    PointDistance out;
    out.distance = result.min_distance;
    out.nearest = result.nearest_points[0];  // on the mesh, whose pose is the identity: world frame
    out.triangle = static_cast<std::int64_t>(result.b1);
    scratch.hint = out.triangle;
    return out;
  }

  /// fcl::distance with a radius-0 capsule (the segment), FCL's own GJK (GST_INDEP) with a 1e-12 tolerance. Against
  /// the exact direct path on lidc0525 (bench_distance --benchmark_filter=accuracy: 20 000 segments of 1.4 mm from
  /// inside-lumen points, 3 758 crossing the wall) it misses 51 crossings (1.4 %, reporting up to ~60 µm instead
  /// of 0), reports 2 false crossings and is off by up to 37 µm elsewhere. libccd (FCL's default solver) was worse
  /// in the same kind of test (2.4 % of crossings missed, up to 105 µm off) and allocates per triangle tested.
  /// FCL reports −1 and no points when the segment touches the wall; then the nearest points are NaN.
  SegmentHit segment_fcl(const Vec3& a, const Vec3& b, const Scratch& scratch) const {
    const Vec3 d = b - a;
    const double length = d.norm();
    const fcl::Capsuled segment(0.0, length);  // along its local z, centred
    fcl::Transform3d pose = fcl::Transform3d::Identity();
    if (length > 0.0) pose.linear() = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), d).toRotationMatrix();
    pose.translation() = 0.5 * (a + b);
    const fcl::DistanceRequestd request(true, false, 0.0, 0.0, 1e-12, fcl::GST_INDEP);
    fcl::DistanceResultd result;
    fcl::distance(&m_model, fcl::Transform3d::Identity(), &segment, pose, request, result);
    SegmentHit out;
    out.triangle = static_cast<std::int64_t>(result.b1);
    if (result.min_distance > 0.0) {
      out.distance_sq = result.min_distance * result.min_distance;
      out.on_mesh = result.nearest_points[0];
      out.on_segment = closest_point_on_segment(out.on_mesh, a, b);
    } else {
      out.distance_sq = 0.0;
      out.on_mesh = out.on_segment = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    }
    scratch.hint = out.triangle;
    return out;
  }

  fcl::BVHModel<BV> m_model;
  std::vector<Triangle> m_triangles;  // = mesh.triangles (FCL keeps the same order: leaf ids index both)
  DistanceTraversal m_traversal;
  int m_depth = 0;
};

}  // namespace

struct DistanceQuery::Impl {
  DistanceQueryOptions options;
  std::unique_ptr<Tree> tree;
};

DistanceQuery::DistanceQuery(const TriangleMesh& mesh, const DistanceQueryOptions& options)
    : m_impl(std::make_unique<Impl>()) {
  usage::note(usage::Component::kDistanceModel);
  if (options.traversal == DistanceTraversal::kFcl && options.bv == DistanceBv::kAabb) {
    throw std::invalid_argument("DistanceQuery: DistanceTraversal::kFcl needs DistanceBv::kRss or kObbRss");
  }
  validate_mesh(mesh, "distance query");
  m_impl->options = options;
  switch (options.bv) {
    case DistanceBv::kAabb: m_impl->tree = std::make_unique<BvhTree<fcl::AABBd>>(mesh, options); break;
    case DistanceBv::kRss: m_impl->tree = std::make_unique<BvhTree<fcl::RSSd>>(mesh, options); break;
    case DistanceBv::kObbRss: m_impl->tree = std::make_unique<BvhTree<fcl::OBBRSSd>>(mesh, options); break;
  }
}

DistanceQuery::~DistanceQuery() = default;
DistanceQuery::DistanceQuery(DistanceQuery&&) noexcept = default;
DistanceQuery& DistanceQuery::operator=(DistanceQuery&&) noexcept = default;

void DistanceQuery::prepare(DistanceWorkspace& workspace) const {
  const std::size_t needed = static_cast<std::size_t>(m_impl->tree->depth()) + 1;
  if (workspace.m_owner != m_impl.get() || workspace.m_stack.size() < needed) {
    workspace.m_stack.assign(needed, {});
    workspace.m_hint = -1;
    workspace.m_owner = m_impl.get();
  }
}

PointDistance DistanceQuery::nearest_point(const Vec3& point, DistanceWorkspace& workspace) const {
  MAGVINE_ASSERT(point.allFinite());
  prepare(workspace);
  return m_impl->tree->nearest_point(point, Scratch{workspace.m_stack, workspace.m_hint, workspace.warm_start});
}

CapsuleDistance DistanceQuery::capsule_distance(const Vec3& a, const Vec3& b, double radius,
                                                DistanceWorkspace& workspace) const {
  MAGVINE_ASSERT(a.allFinite() && b.allFinite() && radius >= 0.0);
  prepare(workspace);
  const SegmentHit hit =
      m_impl->tree->nearest_to_segment(a, b, Scratch{workspace.m_stack, workspace.m_hint, workspace.warm_start});
  CapsuleDistance out;
  out.axis_distance = std::sqrt(hit.distance_sq);
  out.distance = out.axis_distance - radius;
  out.intersects = out.axis_distance < radius;
  out.axis_crosses_wall = hit.distance_sq == 0.0;
  out.on_segment = hit.on_segment;
  out.on_mesh = hit.on_mesh;
  out.on_capsule = out.axis_distance > 0.0
                       ? Vec3(hit.on_segment + (hit.on_mesh - hit.on_segment) * (radius / out.axis_distance))
                       : hit.on_segment;
  out.triangle = hit.triangle;
  return out;
}

double DistanceQuery::lumen_radius(const Vec3& point, DistanceWorkspace& workspace) const {
  return nearest_point(point, workspace).distance;
}

DistanceWorkspace DistanceQuery::make_workspace() const {
  DistanceWorkspace workspace;
  prepare(workspace);
  return workspace;
}

std::size_t DistanceQuery::num_triangles() const { return m_impl->tree->num_triangles(); }
int DistanceQuery::tree_depth() const { return m_impl->tree->depth(); }
const DistanceQueryOptions& DistanceQuery::options() const { return m_impl->options; }

}  // namespace magvine::anatomy
