#include "magvine/anatomy/collision_world.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "magvine/anatomy/edge_bends.hpp"
#include "magvine/anatomy/segment_geometry.hpp"
#include "magvine/core/check.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/multiversion.hpp"
#include "magvine/core/units.hpp"
#include "magvine/core/usage.hpp"
#include "triangle_bvh.hpp"

namespace magvine::anatomy {
namespace {

/// Inclusive face test: a foot counts as inside a triangle down to this fraction of the triangle's size outside
/// it, so a foot exactly on a shared edge or vertex belongs to every triangle sharing it despite rounding (which is
/// ~1e-16 relative); 1e-9 stays far above rounding and far below any geometric feature.
constexpr double kFaceInclusionTol = 1e-9;
/// Ray parity: a crossing within this barycentric margin of an edge or vertex, or a face whose normal is within
/// this cosine of perpendicular to the ray, makes the ray ambiguous (counted 0, 1 or 2 times by rounding).
constexpr double kParityEdgeTol = 1e-9;
constexpr double kParityGrazeTol = 1e-9;
/// Valley bends are clamped to this for the widening behind valleys (TriangleData::valley_margin): behind a
/// right-angled corner the gap would be unbounded.
constexpr double kMaxValleyBend = kPi / 3.0;
/// contains() stops after this many unambiguous rays and returns their majority.
constexpr int kParityVotes = 3;

/// Per-triangle flags: bit k (0..2) = edge k (corner k → corner k+1) gives its own contacts (ridge or boundary).
constexpr std::uint8_t kEdgeMask = 0x7;
constexpr std::uint8_t kDegenerate = 0x8;
/// Bit 4 + k: edge k is a boundary edge (no neighbour), so nothing beyond it reports contacts of its own.
constexpr unsigned kBoundaryShift = 4;

/// What the exact tests read per triangle (those the slot screen passes): one cache line, stored in the BVH's leaf
/// order (slots) with the corners renumbered in order of first use, so that a query reads its leaves' records and
/// their shared corners in short sequential runs.
struct alignas(64) TriangleData {
  Vec3 normal = Vec3::Zero();  ///< unit normal pointing to the free side (zero when degenerate)
  /// normal·corner 0 [m], so the signed plane distance of x is normal·x − offset; +∞ for a degenerate triangle,
  /// whose plane distance is then −∞ and rejects every sphere and capsule without reading the flags.
  double offset = 0.0;
  double bound_radius = 0.0;              ///< largest centroid–corner distance: the centroid's bounding sphere [m]
  std::array<std::uint32_t, 3> corner{};  ///< indices into Tables::points
  std::uint32_t triangle = 0;             ///< index into the mesh's triangles
  std::uint8_t flags = 0;

  /// Inclusion margin of the edge functions [m²].
  double face_tol() const { return kFaceInclusionTol * bound_radius * bound_radius; }
};
static_assert(sizeof(TriangleData) == 64, "one cache line per triangle record");

/// What only edge tests and the widening behind valleys read, per slot beside TriangleData.
struct EdgeArcs {
  /// Per emitting edge: end of its normal arc, cos and sin of the bend angle. Float: a bend to 1e-7 moves a cone
  /// boundary by 1e-7 rad, far below any tessellation angle.
  std::array<float, 3> arc_cos{};
  std::array<float, 3> arc_sin{};
  /// Per valley edge: tan(bend)·|edge| [m]. A centre that has crossed the wall behind a valley by depth h lies in
  /// neither face's prism (the gap between them is h·tan(bend) wide), so each face's prism widens by h·tan(bend)
  /// across its valley edges; the two contacts it then gets are merged when their normals are close.
  std::array<float, 3> valley_margin{};
};

/// Four floats in one SSE register (GCC/Clang vector extension; elementwise operators, scalars broadcast).
using Float4 = float __attribute__((vector_size(16)));

/// A conservative single-precision screen of one slot, read before anything else about its triangle. The three
/// edge functions g_k = (n × e_k)·(x − v_k) (n the outward normal, e_k edge k, v_k its start; ≥ 0 when x lies on
/// the triangle's side of the edge's line) and the free-side plane distance s of an axis point x are one affine map
/// of p = x − Tables::screen_origin, evaluated in four lanes (g0, g1, g2, s) as
///   col[0]·p.x + col[1]·p.y + col[2]·p.z + col[3].
/// The slacks bound the float rounding (16 unit roundoffs of the summed magnitudes, for |p|∞ ≤ Tables::screen_reach)
/// plus the face inclusion tolerance, so a slot the screen rejects is one whose exact double test (SphereQuery,
/// CapsuleQuery) would neither add a contact nor report a candidate: its plane is out of reach, or the axis lies
/// outside the (widened) prism and no emitting edge's line is crossed. The slots the screen passes take the exact
/// path unchanged, in the same order, so contacts are bit-identical to testing every visited triangle exactly. On
/// a raw marching-cubes airway it passes ~23 of the ~100 triangles a sphere query visits.
struct alignas(16) SlotScreen {
  std::array<Float4, 4> col{};  ///< rows g0, g1, g2 [m²] and s [m]; a degenerate triangle has s = +∞
  float slack_g = 0.0F;         ///< bound on the float error of g_k plus the face tolerance, doubled [m²]
  float slack_s = 0.0F;         ///< bound on the float error of s, doubled [m]
  float valley = 0.0F;          ///< largest valley margin of the three edges, rounded up [m]
  std::uint32_t emits = 0;      ///< bit k: edge k gives contacts of its own (TriangleData::flags & kEdgeMask)
};
static_assert(sizeof(SlotScreen) == 80, "four lanes of four floats and the slacks");

struct Tables;
/// The slow path of Tables::ensure: brings a stale slot's records up to date, or waits while another query does.
void refresh_or_wait(const Tables& w, std::uint32_t slot) noexcept;

/// A slot's state while one query fills its records after a refit (Tables::current).
constexpr std::uint32_t kBusy = std::numeric_limits<std::uint32_t>::max();
/// No triangle across an edge (Tables::neighbours).
constexpr std::uint32_t kNoNeighbour = std::numeric_limits<std::uint32_t>::max();

/// Geometry tables shared by the queries; spans point into the owning Impl's mesh copy.
struct Tables {
  std::span<const Vec3> vertices;
  std::span<const Triangle> triangles;
  std::vector<TriangleData> data;   ///< per slot of the BVH (leaf order)
  std::vector<EdgeArcs> arcs;       ///< per slot
  std::vector<SlotScreen> screens;  ///< per slot
  std::vector<Vec3> points;         ///< the corners in order of first use by the slots [m]
  /// The screens' coordinate origin (the mesh's box centre) and the largest |x − origin|∞ their error bounds hold
  /// for [m]; a query axis point farther out skips the screens (exact tests only).
  Vec3 screen_origin = Vec3::Zero();
  double screen_reach = 0.0;

  std::array<const Vec3*, 3> corners(const TriangleData& d) const {
    return {&points[d.corner[0]], &points[d.corner[1]], &points[d.corner[2]]};
  }
  Vec3 centroid(const TriangleData& d) const {
    return (points[d.corner[0]] + points[d.corner[1]] + points[d.corner[2]]) / 3.0;
  }
  /// Vertex → incident triangles, for the vertex normal cones (and the edge bends).
  VertexTriangles incidence;
  double side = -1.0;      ///< free-side normal = side · outward normal
  double merge_cos = 1.0;  ///< cos(merge_angle)
  FreeSide free_side = FreeSide::kInside;
  Vec3 box_min = Vec3::Zero();
  Vec3 box_max = Vec3::Zero();

  // What a refit (CollisionWorld::refit) needs to move the tables without rebuilding them.
  std::vector<std::array<std::uint32_t, 3>> slot_corners;  ///< per slot: TriangleData::corner, packed
  std::vector<std::uint32_t> point_source;                 ///< per point: its mesh vertex
  /// Per triangle and edge: the triangle across it, or kNoNeighbour (the build's topology, which a refit keeps).
  std::vector<std::array<std::uint32_t, 3>> neighbours;
  /// Records filled lazily after a refit. Version 0: built and never refitted, every record current. After a refit
  /// the points, boxes and screen frame are current at once, and a slot's records (data, arcs, screens) are brought
  /// up to date by the first query that reads them, under the slot's own claim in `current` (a version, or kBusy
  /// while a query fills them), so concurrent queries stay safe and each slot is filled once per refit.
  std::uint32_t version = 0;
  std::unique_ptr<std::atomic<std::uint32_t>[]> current;

  /// Makes slot's records current (a no-op for a world never refitted, and for a slot already brought up to date).
  void ensure(std::uint32_t slot) const {
    if (version != 0 && current[slot].load(std::memory_order_acquire) != version) refresh_or_wait(*this, slot);
  }
};

/// Collects contacts into the caller's span: merges close normals (keeps the deepest) and, once full, replaces the
/// shallowest contact with a deeper one.
///
/// Front and back contacts. A face contact whose axis point lies behind the face's plane (s < 0) is a *back*
/// contact: either the body has crossed that wall (keep it: it pushes the body back) or the body sits in another
/// lumen and only reaches this wall from behind through thin tissue, a septum between two branches (drop it: it
/// would push the body through the septum). The nearest feature decides which (the angle-weighted pseudo-normal
/// argument of Bærentzen & Aanæs 2005: the side of the nearest surface point is the side of the point): every
/// face whose foot strictly contains the axis point and every ridge edge inside its cone is a candidate at its
/// distance; when the nearest candidate is in front, the axis point is in the lumen and back contacts are dropped.
/// Back contacts carry kBackBit in `triangle` until finish() (the BVH keeps triangle indices below 2^27).
class ContactSink {
 public:
  static constexpr std::uint32_t kBackBit = 0x80000000u;

  ContactSink(std::span<Contact> out, double merge_cos) : m_out(out), m_merge_cos(merge_cos) {}

  /// A feature at `distance` from the axis point, on its free side (front) or behind it.
  void candidate(double distance, bool front) {
    double& best = front ? m_nearest_front : m_nearest_back;
    best = std::min(best, distance);
  }

  void add(const Vec3& point, const Vec3& normal, double depth, std::uint32_t triangle, bool back = false) {
    if (back) triangle |= kBackBit;
    // Merge with every kept contact within the merge angle, not just the first: a contact between two kept ones
    // (a crease between its two faces) then absorbs both, whatever order the triangles came in.
    std::size_t into = m_count;
    for (std::size_t i = 0; i < m_count;) {
      if (((m_out[i].triangle ^ triangle) & kBackBit) != 0 || m_out[i].normal.dot(normal) < m_merge_cos) {
        ++i;
        continue;
      }
      if (into == m_count) {
        into = i++;
        continue;
      }
      if (m_out[i].depth > m_out[into].depth) m_out[into] = m_out[i];
      m_out[i] = m_out[--m_count];  // absorbed: keep scanning the slot that moved here
    }
    if (into < m_count) {
      if (depth > m_out[into].depth) m_out[into] = Contact{point, normal, depth, triangle};
      return;
    }
    if (m_count < m_out.size()) {
      m_out[m_count++] = Contact{point, normal, depth, triangle};
      return;
    }
    if (m_count == 0) return;
    std::size_t shallowest = 0;
    for (std::size_t i = 1; i < m_count; ++i) {
      if (m_out[i].depth < m_out[shallowest].depth) shallowest = i;
    }
    if (depth > m_out[shallowest].depth) m_out[shallowest] = Contact{point, normal, depth, triangle};
  }

  /// Drops back contacts when the nearest feature is in front, clears the flags, sorts deepest first (ties by
  /// triangle index, so the order is deterministic) and returns the count.
  std::size_t finish() {
    const bool in_lumen = m_nearest_front <= m_nearest_back;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < m_count; ++i) {
      if ((m_out[i].triangle & kBackBit) != 0 && in_lumen) continue;
      m_out[kept] = m_out[i];
      m_out[kept++].triangle &= ~kBackBit;
    }
    m_count = kept;
    std::sort(m_out.begin(), m_out.begin() + static_cast<std::ptrdiff_t>(m_count),
              [](const Contact& a, const Contact& b) {
                return a.depth != b.depth ? a.depth > b.depth : a.triangle < b.triangle;
              });
    return m_count;
  }

 private:
  std::span<Contact> m_out;
  std::size_t m_count = 0;
  double m_merge_cos;
  double m_nearest_front = std::numeric_limits<double>::infinity();
  double m_nearest_back = std::numeric_limits<double>::infinity();
};

/// Whether `f` (from vertex v toward the body) lies in v's normal cone: no edge at v heads toward the body
/// (f·(w − v) ≤ 0 for every neighbour w, the polar of the edge directions). Otherwise a point of that edge is nearer
/// than v, so v is not the nearest feature (e.g. a vertex in the middle of a straight crease or rim).
bool in_vertex_cone(const Tables& w, std::uint32_t v, const Vec3& f) {
  const Vec3& p = w.vertices[v];
  const double fn = f.norm();
  for (std::uint32_t i = w.incidence.first[v]; i < w.incidence.first[v + 1]; ++i) {
    for (const std::uint32_t u : w.triangles[w.incidence.triangles[i]]) {  // every edge at v, each seen twice
      const Vec3 e = w.vertices[u] - p;
      if (f.dot(e) > kFaceInclusionTol * fn * e.norm()) return false;
    }
  }
  return true;
}

/// Contact of body axis point x with edge k of triangle t (a ridge or boundary edge), q its closest point on the
/// edge (`corner` 0 or 1 when q is the edge's start or end vertex, −1 inside). The edge's own region is the arc of
/// normals
///   n(φ) = n_t cos φ + m sin φ,  φ ∈ [0, β],
/// with n_t the free-side normal, m the in-plane unit vector leaving t across the edge and β the bend angle
/// (edge_bends(); π/2 for a boundary edge): when q → x lies in it, normal = that direction, depth = r − |x − q|.
/// Outside the arc the edge is not the nearest feature of a ridge: on t's side (f·m < 0) face t reports, beyond
/// the far end the neighbour face does, and inside the solid under the ridge x projects into one of the two faces.
/// A boundary edge has no neighbour: beyond its far end (x behind the sheet's plane but past the rim) the normal
/// is m, a knife edge, with depth r − (x − q)·m (the along-edge offset included at a corner). At a corner the
/// vertex is the feature: it reports only when x lies in its normal cone, with normal (x − q)/|x − q|.
void edge_contact(const Tables& w, const TriangleData& d, const EdgeArcs& arcs, int k, const Vec3& edge, const Vec3& x,
                  const Vec3& q, int corner, double r, std::uint32_t t, ContactSink& sink) {
  const Vec3 f = x - q;
  if (f.squaredNorm() >= r * r) return;
  const double length = edge.norm();
  const Vec3 m = edge.cross(w.side * d.normal) / length;
  const double fx = f.dot(d.normal);
  const double fy = f.dot(m);
  if (!(fy >= 0.0) || fx * fx + fy * fy == 0.0) return;
  const double c = arcs.arc_cos[static_cast<std::size_t>(k)];
  const double s = arcs.arc_sin[static_cast<std::size_t>(k)];
  const bool in_arc = fx * s - fy * c >= 0.0;
  const bool boundary = (d.flags & (1u << (kBoundaryShift + static_cast<unsigned>(k)))) != 0;
  if (!in_arc && !(boundary && fx * c + fy * s > fx)) return;
  if (corner >= 0) {
    const Triangle& tri = w.triangles[t];
    if (!in_vertex_cone(w, tri[(static_cast<std::size_t>(k) + static_cast<std::size_t>(corner)) % 3], f)) return;
  }
  Vec3 normal;
  double depth = 0.0;
  if (in_arc) {
    const double distance = f.norm();
    normal = corner < 0 ? Vec3((fx * d.normal + fy * m) / std::hypot(fx, fy)) : Vec3(f / distance);
    depth = r - distance;
    sink.candidate(distance, true);
  } else {
    normal = m;  // beyond a rim: the knife edge pushes outward in the sheet's plane
    depth = r - std::hypot(fy, corner < 0 ? 0.0 : f.dot(edge) / length);
  }
  if (depth > 0.0) sink.add(q, normal, depth, t);
}

/// Distance from the segment p0 + s·u, s ∈ [0, 1] (u = 0: a point) to the edges of triangle v[0..2] with edge
/// vectors e: the exact segment–triangle distance when no point of the segment lies over the triangle.
double distance_to_edges(const Vec3& p0, const Vec3& u, const std::array<const Vec3*, 3>& v,
                         const std::array<Vec3, 3>& e) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < 3; ++k) {
    const auto [s, t] = closest_segment_parameters(p0, u, *v[k], e[k]);
    best = std::min(best, (p0 + s * u - (*v[k] + t * e[k])).norm());
  }
  return best;
}

/// x − Tables::screen_origin in float, for the slot screens; false when x lies beyond their reach.
bool screen_point(const Tables& w, const Vec3& x, std::array<float, 3>& p) {
  const Vec3 d = x - w.screen_origin;
  p = {static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z())};
  return d.cwiseAbs().maxCoeff() <= w.screen_reach;
}

/// The lanes (g0, g1, g2, s) of a slot screen at p (see SlotScreen).
Float4 screen_lanes(const SlotScreen& f, const std::array<float, 3>& p) {
  return f.col[0] * p[0] + f.col[1] * p[1] + f.col[2] * p[2] + f.col[3];
}

/// Bit k (k < 3) set where edge lane k of `g` is at most `bound`.
unsigned edge_lanes_at_most(const Float4& g, float bound) {
  return (g[0] <= bound ? 1u : 0u) | (g[1] <= bound ? 2u : 0u) | (g[2] <= bound ? 4u : 0u);
}

/// The radius a screened plane distance must stay below: r rounded up to float, with room for that rounding.
float screen_radius(double r) {
  return static_cast<float>(r) * (1.0F + 1e-6F);
}

/// Sphere against the triangles the BVH reports.
class SphereQuery {
 public:
  SphereQuery(const Tables& w, const Vec3& centre, double radius, ContactSink& sink)
      : m_w(w),
        m_c(centre),
        m_r(radius),
        m_sink(sink),
        m_screen(screen_point(w, centre, m_p)),
        m_r_screen(screen_radius(radius)) {}

  /// Whether the slot may pass the screen for some centre within `margin` of this one and a radius no larger
  /// (ContactCache): each lane moves by at most its gradient's norm times the margin (1e-5 more for the float
  /// norms), so the screen's bounds below are widened by that move.
  bool may_touch_within(std::uint32_t slot, float margin) const {
    if (!m_screen) return true;
    m_w.ensure(slot);
    const SlotScreen& f = m_w.screens[slot];
    const Float4 g = screen_lanes(f, m_p);
    const Float4 norm2 = f.col[0] * f.col[0] + f.col[1] * f.col[1] + f.col[2] * f.col[2];
    const float step = margin * (1.0F + 1e-5F);
    const Float4 move = {std::sqrt(norm2[0]) * step, std::sqrt(norm2[1]) * step, std::sqrt(norm2[2]) * step,
                         std::sqrt(norm2[3]) * step};
    const float s = g[3];
    const float reach = m_r_screen + f.slack_s + move[3];
    if (!(s < reach && s > -reach)) return false;
    const float lowest = -f.slack_g - (std::max(0.0F, -s) + move[3]) * f.valley;
    const Float4 top = g + move;
    if (top[0] >= lowest && top[1] >= lowest && top[2] >= lowest) return true;
    return (edge_lanes_at_most(g - move, f.slack_g) & f.emits) != 0;
  }

  void process(std::uint32_t slot) {
    m_w.ensure(slot);
    if (m_screen && !may_touch(m_w.screens[slot])) return;
    const TriangleData& d = m_w.data[slot];
    const double reach = m_r + d.bound_radius;
    if ((m_c - m_w.centroid(d)).squaredNorm() >= reach * reach) return;
    // Signed distance to the plane, free side positive; the sphere must straddle the plane to touch anything of t.
    const double s = d.normal.dot(m_c) - d.offset;
    if (s >= m_r || s <= -m_r) return;
    const std::uint32_t t = d.triangle;
    const std::array<const Vec3*, 3> v = m_w.corners(d);
    const std::array<Vec3, 3> e = {*v[1] - *v[0], *v[2] - *v[1], *v[0] - *v[2]};
    // Face: the foot of the centre is inside t iff all three edge functions n·(e_k × (c − v_k)) are ≥ 0.
    const Vec3 outward = m_w.side * d.normal;
    const double behind = std::max(0.0, -s);
    std::array<double, 3> g{};  // |e_k| × the foot's signed distance from edge k's line, > 0 on t's side
    bool inside = true;
    bool strict = true;  // inside without the widening: the foot is on t
    const bool emits = (d.flags & kEdgeMask) != 0;
    const double tol = d.face_tol();
    for (std::size_t k = 0; k < 3; ++k) {
      g[k] = outward.dot(e[k].cross(m_c - *v[k]));
      strict = strict && g[k] >= -tol;
      inside = inside && g[k] >= -tol - (behind > 0.0 ? behind * m_w.arcs[slot].valley_margin[k] : 0.0);
      if (!inside && !emits) return;  // most visited triangles: the foot is off t and no edge of t emits
    }
    if (inside) {
      // Reached only through the widening (in the gap behind a valley): behind, at its distance to t's edges.
      m_sink.candidate(strict ? std::abs(s) : distance_to_edges(m_c, Vec3::Zero(), v, e), s >= 0.0 && strict);
      m_sink.add(m_c - s * d.normal, d.normal, m_r - s, t, s < 0.0);
    }
    if ((d.flags & kEdgeMask) == 0) return;
    for (int k = 0; k < 3; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      // An edge's own region lies beyond its line (f·m ≥ 0 in edge_contact): a foot on t's side of the line
      // cannot produce an edge contact, which spares most edge tests on a finely tessellated wall.
      if ((d.flags & (1u << k)) == 0 || g[ku] > tol) continue;
      const double raw = (m_c - *v[ku]).dot(e[ku]) / e[ku].squaredNorm();
      const double tau = std::clamp(raw, 0.0, 1.0);
      const int corner = raw <= 0.0 ? 0 : raw >= 1.0 ? 1 : -1;
      edge_contact(m_w, d, m_w.arcs[slot], k, e[ku], m_c, *v[ku] + tau * e[ku], corner, m_r, t, m_sink);
    }
  }

 private:
  /// The screen's verdict (SlotScreen): false only when the exact test above would do nothing. The bounds below
  /// are the exact test's (|s| < r; g_k ≥ −tol − behind·valley_margin_k for the face; g_k ≤ tol for an emitting
  /// edge) widened by the slacks.
  bool may_touch(const SlotScreen& f) const {
    const Float4 g = screen_lanes(f, m_p);
    const float s = g[3];
    const float reach = m_r_screen + f.slack_s;
    if (!(s < reach && s > -reach)) return false;
    const float lowest = -f.slack_g - std::max(0.0F, -s) * f.valley;
    if (g[0] >= lowest && g[1] >= lowest && g[2] >= lowest) return true;
    return (edge_lanes_at_most(g, f.slack_g) & f.emits) != 0;
  }

  const Tables& m_w;
  Vec3 m_c;
  double m_r;
  ContactSink& m_sink;
  std::array<float, 3> m_p{};
  bool m_screen;
  float m_r_screen;
};

/// Capsule (segment a + τ·ab, τ ∈ [0, 1]) against the triangles the BVH reports.
class CapsuleQuery {
 public:
  CapsuleQuery(const Tables& w, const Vec3& a, const Vec3& b, double radius, ContactSink& sink)
      : m_w(w),
        m_a(a),
        m_ab(b - a),
        m_inv_ab2(1.0 / (b - a).squaredNorm()),
        m_r(radius),
        m_sink(sink),
        m_screen(screen_point(w, a, m_pa) && screen_point(w, b, m_pb)),
        m_r_screen(screen_radius(radius)) {}

  void process(std::uint32_t slot) {
    m_w.ensure(slot);
    if (m_screen && !may_touch(m_w.screens[slot])) return;
    const TriangleData& d = m_w.data[slot];
    const double reach = m_r + d.bound_radius;
    const Vec3 centroid = m_w.centroid(d);
    const double tau_c = std::clamp((centroid - m_a).dot(m_ab) * m_inv_ab2, 0.0, 1.0);
    if ((m_a + tau_c * m_ab - centroid).squaredNorm() >= reach * reach) return;
    // Signed plane distances of the ends (free side positive) are linear along the segment.
    const double sa = d.normal.dot(m_a) - d.offset;
    const double sb = sa + d.normal.dot(m_ab);
    if (!(std::min(sa, sb) < m_r && std::max(sa, sb) > -m_r)) return;  // also rejects degenerate (NaN/∞)
    const std::uint32_t t = d.triangle;
    const std::array<const Vec3*, 3> v = m_w.corners(d);
    const std::array<Vec3, 3> e = {*v[1] - *v[0], *v[2] - *v[1], *v[0] - *v[2]};
    // Face: clip the segment to the prism over t (edge functions g_k(τ) = g_k(0) + τ·slope_k ≥ −tol, the prism
    // optionally widened across valley edges), then take the lowest point of the clipped part along the normal.
    const Vec3 outward = m_w.side * d.normal;
    const std::array<Vec3, 3> inward = {outward.cross(e[0]), outward.cross(e[1]), outward.cross(e[2])};
    const double tol = d.face_tol();
    const EdgeArcs& arcs = m_w.arcs[slot];
    const auto clip = [&](double behind) {
      double lo = 0.0;
      double hi = 1.0;
      for (std::size_t k = 0; k < 3 && lo <= hi; ++k) {
        const double g0 = inward[k].dot(m_a - *v[k]) + tol + (behind > 0.0 ? behind * arcs.valley_margin[k] : 0.0);
        const double slope = inward[k].dot(m_ab);
        if (slope > 0.0) {
          lo = std::max(lo, -g0 / slope);
        } else if (slope < 0.0) {
          hi = std::min(hi, -g0 / slope);
        } else if (g0 < 0.0) {
          hi = -1.0;
        }
      }
      return std::pair<double, double>{lo, hi};
    };
    // The strict prism first: in front, a candidate at the lowest s; the axis crossing the wall over t is a
    // penetration, always kept, with a candidate at 0 behind (so other back contacts stay); wholly behind, a back
    // contact and a candidate at |s_max|. Only when no part of the segment lies over t, the prism widened by the
    // deeper end's depth behind the plane (conservative, as for spheres) may catch a part behind the plane in the
    // gap behind a valley: a back contact, with a candidate at the segment's distance to t's edges.
    auto [lo, hi] = clip(0.0);
    bool widened = false;
    const double behind = std::max(0.0, -std::min(sa, sb));
    if (lo > hi && behind > 0.0) {
      std::tie(lo, hi) = clip(behind);
      widened = true;
    }
    if (lo <= hi) {
      const double s_lo = sa + lo * (sb - sa);
      const double s_hi = sa + hi * (sb - sa);
      const double s_min = std::min(s_lo, s_hi);
      const double s_max = std::max(s_lo, s_hi);
      if (s_min < m_r && s_max > -m_r && (!widened || s_min < 0.0)) {
        const Vec3 x = m_a + (s_lo <= s_hi ? lo : hi) * m_ab;
        bool keep = false;
        if (widened) {
          m_sink.candidate(distance_to_edges(m_a, m_ab, v, e), false);
        } else if (s_min >= 0.0) {
          m_sink.candidate(s_min, true);
        } else if (s_max > 0.0) {
          m_sink.candidate(0.0, false);
          keep = true;
        } else {
          m_sink.candidate(-s_max, false);
        }
        m_sink.add(x - s_min * d.normal, d.normal, m_r - s_min, t, s_min < 0.0 && !keep);
      }
    }
    if ((d.flags & kEdgeMask) == 0) return;
    for (int k = 0; k < 3; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      // As for spheres: a segment whose ends both lie on t's side of the edge's line cannot reach its region.
      if ((d.flags & (1u << k)) == 0 ||
          (inward[ku].dot(m_a - *v[ku]) > tol && inward[ku].dot(m_a + m_ab - *v[ku]) > tol)) {
        continue;
      }
      const auto [s, u] = closest_segment_parameters(m_a, m_ab, *v[ku], e[ku]);
      const int corner = u <= 0.0 ? 0 : u >= 1.0 ? 1 : -1;
      edge_contact(m_w, d, arcs, k, e[ku], m_a + s * m_ab, *v[ku] + u * e[ku], corner, m_r, t, m_sink);
    }
  }

 private:
  /// The screen's verdict, as for spheres with the lanes at both ends. The plane distance and the edge functions
  /// are linear along the segment, so the exact test's conditions are: min s < r and max s > −r; some part of the
  /// segment with every edge function ≥ −tol − behind·valley_margin_k (the face clip, done here in float on the
  /// lanes: each lane's float line lies within its rounding bound of the exact one, which `lowest` covers, and the
  /// float divisions move a clip parameter by a few roundoffs of its value, which 1e-6 covers on [0, 1]); or an
  /// emitting edge's function ≤ tol at an end.
  bool may_touch(const SlotScreen& f) const {
    const Float4 ga = screen_lanes(f, m_pa);
    const Float4 gb = screen_lanes(f, m_pb);
    const float s_lo = std::min(ga[3], gb[3]);
    const float s_hi = std::max(ga[3], gb[3]);
    const float reach = m_r_screen + f.slack_s;
    if (!(s_lo < reach && s_hi > -reach)) return false;
    const float lowest = -f.slack_g - std::max(0.0F, -s_lo) * f.valley;
    const Float4 slope = gb - ga;
    const Float4 cross = (lowest - ga) / slope;  // where each lane's line meets `lowest` (±∞ or NaN when flat)
    float lo = 0.0F;
    float hi = 1.0F;
    for (int k = 0; k < 3; ++k) {
      if (slope[k] > 0.0F) {
        lo = std::max(lo, cross[k]);
      } else if (slope[k] < 0.0F) {
        hi = std::min(hi, cross[k]);
      } else if (ga[k] < lowest) {
        hi = -1.0F;
      }
    }
    if (lo <= hi + 1e-6F) return true;
    const Float4 h = (ga < gb) ? ga : gb;  // the smaller end per lane
    return (edge_lanes_at_most(h, f.slack_g) & f.emits) != 0;
  }

  const Tables& m_w;
  Vec3 m_a;
  Vec3 m_ab;
  double m_inv_ab2;
  double m_r;
  ContactSink& m_sink;
  std::array<float, 3> m_pa{};
  std::array<float, 3> m_pb{};
  bool m_screen;
  float m_r_screen;
};

/// Ray o + s·dir against triangle t (Möller–Trumbore): distance s and barycentrics (b0, b1, b2) of the plane
/// crossing, and the cosine between the ray and the outward normal. False only when the ray is parallel.
struct RayCrossing {
  double distance = 0.0;
  double b_min = 0.0;  ///< smallest barycentric coordinate: < 0 outside, ≈ 0 on an edge or vertex
  double cosine = 0.0;
};

bool cross_triangle(const Tables& w, const TriangleData& d, const Vec3& o, const Vec3& dir, RayCrossing& out) {
  const std::array<const Vec3*, 3> v = w.corners(d);
  const Vec3& v0 = *v[0];
  const Vec3 e1 = *v[1] - v0;
  const Vec3 e2 = *v[2] - v0;
  const Vec3 p = dir.cross(e2);
  const double det = e1.dot(p);
  if (det == 0.0) return false;
  const double inv = 1.0 / det;
  const Vec3 sv = o - v0;
  const double b1 = sv.dot(p) * inv;
  const Vec3 qv = sv.cross(e1);
  const double b2 = dir.dot(qv) * inv;
  out.distance = e2.dot(qv) * inv;
  out.b_min = std::min({1.0 - b1 - b2, b1, b2});
  out.cosine = w.side * d.normal.dot(dir);
  return true;
}

/// Nearest hit along a ray (inclusive of edges and vertices).
class RayQuery {
 public:
  RayQuery(const Tables& w, const Vec3& origin, const Vec3& dir, double max_distance)
      : m_w(w), m_o(origin), m_dir(dir), m_best(max_distance) {}

  /// Current search length: hits beyond it cannot improve the result.
  double reach() const { return m_best; }

  void process(const TriangleData& d) {
    if ((d.flags & kDegenerate) != 0) return;
    const std::uint32_t t = d.triangle;
    RayCrossing x;
    if (!cross_triangle(m_w, d, m_o, m_dir, x)) return;
    if (x.b_min < -kFaceInclusionTol || x.distance < 0.0 || x.distance > m_best) return;
    if (m_found && x.distance == m_best && t > m_hit) return;  // exact ties: the lower index, for determinism
    m_best = x.distance;
    m_hit = t;
    m_normal = d.normal;
    m_cosine = x.cosine;
    m_found = true;
  }

  std::optional<RayHit> result() const {
    if (!m_found) return std::nullopt;
    const Vec3 outward = m_w.side * m_normal;
    const bool front = m_cosine < 0.0;
    return RayHit{m_best, m_o + m_best * m_dir, front ? outward : Vec3(-outward), m_hit, front};
  }

 private:
  const Tables& m_w;
  Vec3 m_o;
  Vec3 m_dir;
  double m_best;
  std::uint32_t m_hit = 0;
  Vec3 m_normal = Vec3::Zero();
  double m_cosine = 0.0;
  bool m_found = false;
};

/// Counts the crossings of a ray with the surface for the parity test, flagging rays that pass too close to an
/// edge or vertex, graze a face or start on the surface.
class ParityQuery {
 public:
  ParityQuery(const Tables& w, const Vec3& origin, const Vec3& dir, double length)
      : m_w(w), m_o(origin), m_dir(dir), m_length(length) {}

  void process(const TriangleData& d) {
    if (m_ambiguous) return;
    if ((d.flags & kDegenerate) != 0) return;
    RayCrossing x;
    const bool crosses = cross_triangle(m_w, d, m_o, m_dir, x);
    if (!crosses || std::abs(x.cosine) < kParityGrazeTol) {
      // (Nearly) in the triangle's plane: ambiguous if the ray passes through the bounding sphere.
      const Vec3 oc = m_w.centroid(d) - m_o;
      const double along = oc.dot(m_dir);
      if (along >= -d.bound_radius && along <= m_length + d.bound_radius &&
          (oc - along * m_dir).squaredNorm() <= d.bound_radius * d.bound_radius) {
        m_ambiguous = true;
      }
      return;
    }
    if (x.b_min < -kParityEdgeTol || x.distance > m_length) return;
    const double surface_tol = kParityEdgeTol * d.bound_radius;
    if (x.distance < -surface_tol) return;
    if (x.b_min <= kParityEdgeTol || x.distance <= surface_tol) {
      m_ambiguous = true;
      return;
    }
    ++m_crossings;
  }

  bool ambiguous() const { return m_ambiguous; }
  bool odd() const { return (m_crossings & 1) != 0; }

 private:
  const Tables& m_w;
  Vec3 m_o;
  Vec3 m_dir;
  double m_length;
  int m_crossings = 0;
  bool m_ambiguous = false;
};

void validate(const TriangleMesh& mesh, const CollisionWorldOptions& options) {
  const std::string where = "CollisionWorld";
  validate_mesh(mesh, where);
  if (!(options.merge_angle >= 0.0 && options.merge_angle < kPi / 2)) {
    throw InputError(where + ": merge_angle must be in [0, pi/2) rad (got " + std::to_string(options.merge_angle) +
                     ")");
  }
}

/// The slots' corners: TriangleData::corner (and slot_corners) index `points`, the mesh's vertices renumbered in
/// order of first use by the slots (point_source maps them back); TriangleData::triangle the slot's triangle.
void fill_corners(Tables& w, std::span<const std::uint32_t> order) {
  constexpr std::uint32_t kUnused = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> renumber(w.vertices.size(), kUnused);
  w.points.clear();
  w.point_source.clear();
  w.points.reserve(w.vertices.size());
  w.point_source.reserve(w.vertices.size());
  w.slot_corners.resize(order.size());
  for (std::size_t slot = 0; slot < order.size(); ++slot) {
    const std::uint32_t t = order[slot];
    const Triangle& tri = w.triangles[t];
    TriangleData& d = w.data[slot];
    for (std::size_t k = 0; k < 3; ++k) {
      std::uint32_t& to = renumber[tri[k]];
      if (to == kUnused) {
        to = static_cast<std::uint32_t>(w.points.size());
        w.points.push_back(w.vertices[tri[k]]);
        w.point_source.push_back(tri[k]);
      }
      d.corner[k] = to;
    }
    w.slot_corners[slot] = d.corner;
    d.triangle = t;
  }
}

/// A slot's record from its corners and its triangle's unit outward normal (zero: degenerate, flagged).
void fill_record(Tables& w, std::size_t slot, const Vec3& outward) {
  TriangleData& d = w.data[slot];
  const std::array<const Vec3*, 3> v = w.corners(d);
  const Vec3 centroid = w.centroid(d);
  d.bound_radius = std::sqrt(
      std::max({(*v[0] - centroid).squaredNorm(), (*v[1] - centroid).squaredNorm(), (*v[2] - centroid).squaredNorm()}));
  d.flags = 0;
  if (outward.isZero()) {
    d.normal = Vec3::Zero();
    d.flags = kDegenerate;
    d.offset = std::numeric_limits<double>::infinity();
    return;
  }
  d.normal = w.side * outward;
  d.offset = d.normal.dot(*v[0]);
}

/// A slot's edge classes from its triangle's edge bends (edge_bends.hpp). From the free side, a ridge is an edge
/// convex toward the free side: concave seen from outside when the free side is inside. Flat edges and valleys emit
/// nothing; valleys widen the face regions behind the wall. `stats` (optional) counts the classes.
void fill_arcs(Tables& w, std::size_t slot, const std::array<EdgeBend, 3>& bends, CollisionWorldStats* stats) {
  TriangleData& d = w.data[slot];
  EdgeArcs& arcs = w.arcs[slot];
  arcs = EdgeArcs{};
  const std::uint32_t t = d.triangle;
  if ((d.flags & kDegenerate) != 0) {
    if (stats != nullptr) ++stats->degenerate_triangles;
    return;
  }
  for (std::size_t k = 0; k < 3; ++k) {
    const EdgeBend& edge = bends[k];
    bool emits = false;
    double c = 0.0;  // boundary: the arc runs a quarter turn, to the in-plane direction
    double sn = 1.0;
    if (edge.boundary) {
      emits = true;
      if (stats != nullptr) ++stats->boundary_edges;
    } else if (edge.sin != 0.0 || edge.cos < 0.0) {
      if (edge.convex == (w.free_side == FreeSide::kOutside)) {
        // Both triangles at a ridge see the same arc of normals and would report the same contact: the one with
        // the lower index owns it (both are always visited when a body reaches the edge).
        emits = t < edge.neighbour;
        c = edge.cos;
        sn = edge.sin;
        if (stats != nullptr) ++stats->ridge_edges;
      } else {
        const Triangle& tri = w.triangles[t];
        const double length = (w.vertices[tri[(k + 1) % 3]] - w.vertices[tri[k]]).norm();
        // tan(min(bend, kMaxValleyBend)); cos(kMaxValleyBend) = 1/2.
        const double tan = edge.cos > 0.5 ? edge.sin / edge.cos : std::tan(kMaxValleyBend);
        arcs.valley_margin[k] = static_cast<float>(tan * length);
      }
    }
    if (emits) {
      d.flags = static_cast<std::uint8_t>(d.flags | (1u << k));
      if (edge.boundary) d.flags = static_cast<std::uint8_t>(d.flags | (1u << (kBoundaryShift + k)));
      arcs.arc_cos[k] = static_cast<float>(c);
      arcs.arc_sin[k] = static_cast<float>(sn);
    }
  }
}

/// The screens' coordinate frame from the mesh's box (SlotScreen).
void set_screen_frame(Tables& w) {
  w.screen_origin = 0.5 * (w.box_min + w.box_max);
  // Bodies reach the wall from at most their radius away; beyond a box half-diagonal past the box the exact tests
  // alone decide (the bounds grow with the reach).
  w.screen_reach = (w.box_max - w.box_min).norm();
}

/// A slot's screen (SlotScreen), from its record and edge classes already filled.
void fill_screen(Tables& w, std::size_t slot) {
  constexpr double kUnitRoundoff = 0x1p-24;  // float
  constexpr double kRoundoffs = 16.0;        // per summed magnitude: a 3-term dot product, its constant, the inputs
  const double reach = w.screen_reach;
  const auto lanes = [](double g0, double g1, double g2, double s) {
    return Float4{static_cast<float>(g0), static_cast<float>(g1), static_cast<float>(g2), static_cast<float>(s)};
  };
  const TriangleData& d = w.data[slot];
  SlotScreen& f = w.screens[slot];
  f = SlotScreen{};
  if ((d.flags & kDegenerate) != 0) {
    f.col[3] = lanes(0.0, 0.0, 0.0, std::numeric_limits<double>::infinity());  // s = +∞: out of every reach
    return;
  }
  const std::array<const Vec3*, 3> v = w.corners(d);
  const Vec3 outward = w.side * d.normal;
  std::array<Vec3, 4> rows;
  std::array<double, 4> constant{};
  for (std::size_t k = 0; k < 3; ++k) {
    rows[k] = outward.cross(*v[(k + 1) % 3] - *v[k]);
    constant[k] = -rows[k].dot(*v[k] - w.screen_origin);
  }
  rows[3] = d.normal;
  constant[3] = d.normal.dot(w.screen_origin) - d.offset;
  std::array<double, 4> error{};
  for (std::size_t k = 0; k < 4; ++k) {
    error[k] = kRoundoffs * kUnitRoundoff * (rows[k].cwiseAbs().sum() * reach + std::abs(constant[k]));
  }
  for (int axis = 0; axis < 3; ++axis) {
    f.col[static_cast<std::size_t>(axis)] = lanes(rows[0][axis], rows[1][axis], rows[2][axis], rows[3][axis]);
  }
  f.col[3] = lanes(constant[0], constant[1], constant[2], constant[3]);
  const EdgeArcs& arcs = w.arcs[slot];
  const double valley = std::max({arcs.valley_margin[0], arcs.valley_margin[1], arcs.valley_margin[2]}) * (1.0 + 1e-6);
  f.valley = static_cast<float>(valley);
  f.slack_s = static_cast<float>(2.0 * error[3]);
  f.slack_g = static_cast<float>(2.0 * (d.face_tol() + std::max({error[0], error[1], error[2]}) + error[3] * valley));
  f.emits = d.flags & kEdgeMask;
}

/// A slot's records for its triangle's current corners (after a refit): the normal from the moved vertices, the
/// bends across the build's edge topology (an edge whose neighbour has become degenerate is a boundary), the arcs and
/// the screen. The same laws as the build's, so the records equal a fresh build's on the moved mesh.
void refresh_slot(Tables& w, std::uint32_t slot) noexcept {
  const std::uint32_t t = w.data[slot].triangle;
  const Triangle& tri = w.triangles[t];
  const Vec3 nt = triangle_unit_normal(w.vertices[tri[0]], w.vertices[tri[1]], w.vertices[tri[2]]);
  fill_record(w, slot, nt);
  std::array<EdgeBend, 3> bends{};
  if (!nt.isZero()) {
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t u = w.neighbours[t][k];
      if (u == kNoNeighbour) continue;
      const Triangle& o = w.triangles[u];
      const Vec3 nu = triangle_unit_normal(w.vertices[o[0]], w.vertices[o[1]], w.vertices[o[2]]);
      if (!nu.isZero()) bends[k] = bend_across(w.vertices, tri, k, nt, u, o, nu);
    }
  }
  fill_arcs(w, slot, bends, nullptr);
  fill_screen(w, slot);
}

void refresh_or_wait(const Tables& w, std::uint32_t slot) noexcept {
  std::atomic<std::uint32_t>& state = w.current[slot];
  std::uint32_t seen = state.load(std::memory_order_acquire);
  while (seen != w.version) {
    if (seen != kBusy) {
      if (state.compare_exchange_weak(seen, kBusy, std::memory_order_acquire, std::memory_order_acquire)) {
        // This query holds the slot's claim: its records are written by no one else. The tables are never const
        // objects (CollisionWorld::Impl owns them); queries see them through const references.
        refresh_slot(const_cast<Tables&>(w), slot);
        state.store(w.version, std::memory_order_release);
        return;
      }
      continue;  // `seen` holds the state now
    }
    std::this_thread::yield();  // another query is filling it
    seen = state.load(std::memory_order_acquire);
  }
}

}  // namespace

struct CollisionWorld::Impl {
  Impl(const TriangleMesh& source, const CollisionWorldOptions& opts);
  /// The tables of the mesh as it is now, over the BVH's slot order.
  void fill_tables();

  TriangleMesh mesh;
  CollisionWorldOptions options;
  CollisionWorldStats stats;
  Tables tables;
  std::optional<detail::TriangleBvh> bvh;
  /// Unique to this world in the process (from 1), so that a NearCache filled in a world since destroyed is not
  /// taken for one built later at the same address.
  std::uint64_t id = next_id();

  static std::uint64_t next_id() {
    static std::atomic<std::uint64_t> counter{0};
    return ++counter;
  }
};

CollisionWorld::Impl::Impl(const TriangleMesh& source, const CollisionWorldOptions& opts)
    : mesh((validate(source, opts), source)), options(opts) {
  const auto start = std::chrono::steady_clock::now();
  Tables& w = tables;
  w.vertices = mesh.vertices;
  w.triangles = mesh.triangles;
  w.side = options.free_side == FreeSide::kInside ? -1.0 : 1.0;
  w.free_side = options.free_side;
  w.merge_cos = std::cos(options.merge_angle);
  bvh.emplace(mesh.vertices, mesh.triangles);
  fill_tables();
  stats.triangles = mesh.triangles.size();
  stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void CollisionWorld::Impl::fill_tables() {
  Tables& w = tables;
  const Aabb box = bounding_box(mesh);
  w.box_min = box.min;
  w.box_max = box.max;
  w.incidence = vertex_triangles(mesh);
  const std::size_t n = mesh.triangles.size();
  w.data.assign(n, TriangleData{});
  w.arcs.assign(n, EdgeArcs{});
  w.screens.assign(n, SlotScreen{});
  stats.degenerate_triangles = stats.ridge_edges = stats.boundary_edges = 0;
  fill_corners(w, bvh->order());  // records in the BVH's leaf order
  for (std::size_t slot = 0; slot < n; ++slot) fill_record(w, slot, w.incidence.normals[w.data[slot].triangle]);
  const std::vector<std::array<EdgeBend, 3>> bends = edge_bends(mesh, w.incidence);
  w.neighbours.resize(n);
  for (std::size_t t = 0; t < n; ++t) {
    for (std::size_t k = 0; k < 3; ++k)
      w.neighbours[t][k] = bends[t][k].boundary ? kNoNeighbour : bends[t][k].neighbour;
  }
  for (std::size_t slot = 0; slot < n; ++slot) fill_arcs(w, slot, bends[w.data[slot].triangle], &stats);
  set_screen_frame(w);
  for (std::size_t slot = 0; slot < n; ++slot) fill_screen(w, slot);
  std::vector<Vec3>().swap(w.incidence.normals);  // the queries read only the incidence lists
}

namespace {

/// Whether every coordinate is finite (one pass over the doubles, vectorised).
MAGVINE_HOT_KERNEL bool all_finite(std::span<const Vec3> v) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  const double* x = v.empty() ? nullptr : v.front().data();
  const std::size_t n = 3 * v.size();
  // x·0 is 0 for a finite x and NaN for ±∞ and NaN; four sums of them, in lanes the compiler can vectorise.
  std::array<double, 4> zero{};
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    for (std::size_t k = 0; k < 4; ++k) zero[k] += x[i + k] * 0.0;
  }
  for (; i < n; ++i) zero[0] += x[i] * 0.0;
  return zero[0] + zero[1] + zero[2] + zero[3] == 0.0;
}

/// Copies `from` to `to` and returns their box.
MAGVINE_HOT_KERNEL std::pair<Vec3, Vec3> copy_with_box(std::span<const Vec3> from, Vec3* to) {
  detail::ScalarBox box;
  for (std::size_t i = 0; i < from.size(); ++i) {
    to[i] = from[i];
    box.add(from[i]);
  }
  return box.box();
}

/// to[p] = from[source[p]] for every p, and the box of what was gathered.
MAGVINE_HOT_KERNEL std::pair<Vec3, Vec3> gather_with_box(std::span<const Vec3> from,
                                                         std::span<const std::uint32_t> source, Vec3* to) {
  detail::ScalarBox box;
  for (std::size_t p = 0; p < source.size(); ++p) {
    const Vec3& v = from[source[p]];
    to[p] = v;
    box.add(v);
  }
  return box.box();
}

}  // namespace

CollisionWorld::CollisionWorld(const TriangleMesh& mesh, const CollisionWorldOptions& options)
    : m_impl(std::make_unique<Impl>(mesh, options)) {
  usage::note(usage::Component::kCollisionWorld);
}
void CollisionWorld::refit(std::span<const Vec3> vertices) {
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *m_impl;
  if (vertices.size() != m.mesh.vertices.size()) {
    throw InputError("collision world refit: " + std::to_string(vertices.size()) + " vertices for a mesh of " +
                     std::to_string(m.mesh.vertices.size()));
  }
  if (!all_finite(vertices)) throw InputError("collision world refit: a vertex is not finite");
  // What may allocate comes first, so that nothing below can throw with the world half moved.
  Tables& w = m.tables;
  const std::size_t n = w.data.size();
  if (!w.current) w.current = std::make_unique<std::atomic<std::uint32_t>[]>(n);  // every slot stale (0)
  m.bvh->prepare_refit(w.slot_corners);
  // The vertices and the mesh's box; the corners in slot order and their box; the BVH's boxes; the screen frame.
  // The slots' records follow lazily, each at the first query that reads it (Tables::ensure).
  const auto [all_lo, all_hi] = copy_with_box(vertices, m.mesh.vertices.data());
  w.box_min = all_lo;
  w.box_max = all_hi;
  const auto [lo, hi] = gather_with_box(vertices, w.point_source, w.points.data());
  m.bvh->refit(w.points, lo, hi);
  set_screen_frame(w);
  if (w.version + 1 == kBusy) {
    // The versions ran out (after 2^32 − 2 refits): every slot stale again.
    for (std::size_t slot = 0; slot < n; ++slot) w.current[slot].store(0, std::memory_order_relaxed);
    w.version = 0;
  }
  ++w.version;
  m.id = Impl::next_id();  // caches filled before hold the old geometry
  m.stats.refit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::uint64_t CollisionWorld::geometry_id() const { return m_impl->id; }

CollisionWorld::~CollisionWorld() = default;
CollisionWorld::CollisionWorld(CollisionWorld&&) noexcept = default;
CollisionWorld& CollisionWorld::operator=(CollisionWorld&&) noexcept = default;

MAGVINE_HOT_KERNEL std::size_t CollisionWorld::sphere_contacts(const Vec3& centre, double radius,
                                                               std::span<Contact> out) const {
  MAGVINE_ASSERT(radius > 0.0 && centre.allFinite());
  const Tables& w = m_impl->tables;
  ContactSink sink(out, w.merge_cos);
  SphereQuery query(w, centre, radius, sink);
  m_impl->bvh->visit_slots(detail::SphereBoxTest(centre, radius), [&](std::uint32_t slot) { query.process(slot); });
  return sink.finish();
}

struct ContactCache::Storage {
  /// The kept leaves in the walk's order, four to a group in the BVH's node layout (child k: kLeafBit | first << 4 |
  /// count, `first` indexing `slots`; unused lanes empty), so the node test of the walk decides them.
  std::vector<detail::TriangleBvh::Node> groups;
  std::vector<std::uint32_t> slots;
  std::size_t group_count = 0;
  std::size_t leaf_count = 0;  ///< leaves in the groups
  std::size_t slot_count = 0;
  std::uint64_t world = 0;     ///< the id of the world (and refit) that filled it; 0 when empty
  Vec3 centre = Vec3::Zero();  ///< fill centre [m]
  double radius = 0.0;         ///< fill radius [m]

  /// Appends a leaf with its box and the kept slots [first, slot_count); false when full.
  bool add_leaf(const detail::ChildBox& box, std::size_t first) {
    const std::size_t lane = leaf_count % 4;
    if (lane == 0) {
      if (group_count == groups.size()) return false;
      groups[group_count++] = detail::TriangleBvh::empty_node();
    }
    detail::TriangleBvh::Node& g = groups[group_count - 1];
    g.lo_x[lane] = box.lo[0];
    g.lo_y[lane] = box.lo[1];
    g.lo_z[lane] = box.lo[2];
    g.hi_x[lane] = box.hi[0];
    g.hi_y[lane] = box.hi[1];
    g.hi_z[lane] = box.hi[2];
    g.child[lane] = detail::TriangleBvh::kLeafBit | static_cast<std::uint32_t>(first << 4) |
                    static_cast<std::uint32_t>(slot_count - first);
    ++leaf_count;
    return true;
  }
};

ContactCache::ContactCache(double margin, std::size_t capacity) : m_margin(margin) {
  if (!(margin >= 0.0 && std::isfinite(margin))) {
    throw InputError("ContactCache: margin must be finite and >= 0 m (got " + std::to_string(margin) + ")");
  }
  // A leaf holds at least one kept slot, so `capacity` leaves always suffice; slot indices fit a leaf's 27 bits.
  capacity = std::min<std::size_t>(capacity, std::size_t{1} << 26);
  m_storage = std::make_unique<Storage>();
  m_storage->groups.resize((capacity + 3) / 4);
  m_storage->slots.resize(capacity);
}
ContactCache::~ContactCache() = default;
ContactCache::ContactCache(ContactCache&&) noexcept = default;
ContactCache& ContactCache::operator=(ContactCache&&) noexcept = default;

void ContactCache::clear() {
  m_storage->world = 0;
}
bool ContactCache::filled() const {
  return m_storage->world != 0;
}

MAGVINE_HOT_KERNEL std::size_t CollisionWorld::sphere_contacts(const Vec3& centre, double radius,
                                                               std::span<Contact> out, ContactCache& cache) const {
  MAGVINE_ASSERT(radius > 0.0 && centre.allFinite());
  const Tables& w = m_impl->tables;
  ContactCache::Storage& kept = *cache.m_storage;
  ContactSink sink(out, w.merge_cos);
  SphereQuery query(w, centre, radius, sink);
  const double r2 = radius * radius;
  // In the cache's reach: every leaf within r of the centre is within r + margin of the fill centre, where the
  // fill kept every leaf (less 1e-12 of the coordinates for the rounding of the leaf tests; the fill centre itself
  // always qualifies). The walk's node test then picks, of the kept leaves, exactly the walk's, in its order.
  const double moved = (centre - kept.centre).norm();
  const double room = 1e-12 * (centre.cwiseAbs().maxCoeff() + kept.radius);
  if (kept.world == m_impl->id && radius <= kept.radius && (moved == 0.0 || moved + room <= cache.m_margin)) {
    const detail::SphereBoxTest test(centre, radius);
    for (std::size_t i = 0; i < kept.group_count; ++i) {
      const detail::TriangleBvh::Node& group = kept.groups[i];
      unsigned mask = test(group);
      while (mask != 0) {
        const int k = __builtin_ctz(mask);
        mask &= mask - 1;
        const std::uint32_t leaf = group.child[static_cast<std::size_t>(k)];
        const std::uint32_t first = (leaf & ~detail::TriangleBvh::kLeafBit) >> 4;
        for (std::uint32_t j = first; j < first + (leaf & 0xFu); ++j) query.process(kept.slots[j]);
      }
    }
    return sink.finish();
  }
  // Refill: walk the leaves within r + margin, keep those triangles that may touch within the margin, and answer
  // this query from the leaves within r (the plain walk's leaves, in its order).
  kept.world = 0;
  kept.group_count = 0;
  kept.leaf_count = 0;
  kept.slot_count = 0;
  bool fits = true;
  const auto margin = static_cast<float>(cache.m_margin);
  m_impl->bvh->walk_leaves(detail::SphereBoxTest(centre, radius + cache.m_margin),
                           [&](const detail::TriangleBvh::Node& node, int k) {
                             const std::uint32_t child = node.child[static_cast<std::size_t>(k)];
                             const std::uint32_t first = (child & ~detail::TriangleBvh::kLeafBit) >> 4;
                             const std::uint32_t end = first + (child & 0xFu);
                             const detail::ChildBox box = detail::child_box(node, k);
                             const std::size_t start = kept.slot_count;
                             for (std::uint32_t slot = first; slot < end && fits; ++slot) {
                               if (!query.may_touch_within(slot, margin)) continue;
                               fits = kept.slot_count < kept.slots.size();
                               if (fits) kept.slots[kept.slot_count++] = slot;
                             }
                             if (fits && kept.slot_count > start) fits = kept.add_leaf(box, start);
                             if (!detail::sphere_touches(box, centre, r2)) return;
                             for (std::uint32_t slot = first; slot < end; ++slot) query.process(slot);
                           });
  if (fits) {
    kept.world = m_impl->id;
    kept.centre = centre;
    kept.radius = radius;
  }
  return sink.finish();
}

MAGVINE_HOT_KERNEL std::size_t CollisionWorld::capsule_contacts(const Vec3& a, const Vec3& b, double radius,
                                                                std::span<Contact> out) const {
  MAGVINE_ASSERT(radius > 0.0 && a.allFinite() && b.allFinite());
  // A segment too short to define a direction is a sphere (its length is far below any triangle size).
  if ((b - a).squaredNorm() <= 1e-24 * radius * radius) return sphere_contacts(0.5 * (a + b), radius, out);
  const Tables& w = m_impl->tables;
  ContactSink sink(out, w.merge_cos);
  CapsuleQuery query(w, a, b, radius, sink);
  const Vec3 pad = Vec3::Constant(radius);
  const Vec3 lo = a.cwiseMin(b) - pad;
  const Vec3 hi = a.cwiseMax(b) + pad;
  m_impl->bvh->visit_slots(detail::BoxBoxTest(lo, hi), [&](std::uint32_t slot) { query.process(slot); });
  return sink.finish();
}

namespace {

/// triangles_within's test of one triangle (slot) and its insertion into `out`, nearest first and ties by triangle
/// index, so that the answer depends only on which triangles lie within the radius, not on the order they are
/// tested in (a NearCache's kept triangles and the BVH walk give the same bits).
struct NearSink {
  const Tables& w;
  const Vec3& point;
  double radius;
  std::span<NearTriangle> out;
  std::size_t found = 0;
  std::size_t kept = 0;
  bool sorted = false;  ///< out[0, kept) in order (from the first triangle that found it full on)
  double stop = -1.0;   ///< a triangle within this distance ends the query (`stopped`)
  bool stopped = false;

  static bool before(const NearTriangle& a, const NearTriangle& b) {
    return a.distance < b.distance || (a.distance == b.distance && a.triangle < b.triangle);
  }

  /// Whether the triangle in `slot` lies within the radius (and, then, records it). Kept unordered while the span has
  /// room (sorted once by finish()); once full, in order, the farthest kept one making room for a nearer one.
  bool process(std::uint32_t slot) {
    if (stopped) return false;
    w.ensure(slot);
    const TriangleData& d = w.data[slot];
    // Farther from the triangle's plane than the radius (a degenerate triangle's offset is infinite: always).
    if (!(std::abs(d.normal.dot(point) - d.offset) <= radius)) return false;
    if ((w.centroid(d) - point).squaredNorm() > (d.bound_radius + radius) * (d.bound_radius + radius)) return false;
    const auto v = w.corners(d);
    const Vec3 q = closest_point_on_triangle(point, *v[0], *v[1], *v[2]);
    const double distance = (q - point).norm();
    if (distance > radius) return false;
    ++found;
    stopped = distance <= stop;
    if (out.empty()) return true;
    const NearTriangle t{q, distance, d.triangle};
    if (kept < out.size()) {
      out[kept++] = t;
      return true;
    }
    if (!sorted) {
      std::sort(out.begin(), out.end(), before);
      sorted = true;
    }
    if (!before(t, out[kept - 1])) return true;
    std::size_t i = kept - 1;
    for (; i > 0 && before(t, out[i - 1]); --i) out[i] = out[i - 1];
    out[i] = t;
    return true;
  }

  /// The count within the radius, with out[0, min(found, size)) nearest first.
  std::size_t finish() {
    if (!sorted) std::sort(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(kept), before);
    return found;
  }
};

}  // namespace

MAGVINE_HOT_KERNEL std::size_t CollisionWorld::triangles_within(const Vec3& point, double radius,
                                                                std::span<NearTriangle> out) const {
  MAGVINE_ASSERT(radius > 0.0 && point.allFinite());
  NearSink sink{m_impl->tables, point, radius, out};
  m_impl->bvh->visit_slots(detail::SphereBoxTest(point, radius), [&](std::uint32_t slot) { sink.process(slot); });
  return sink.finish();
}

NearCache::NearCache(double margin, std::size_t capacity) : m_margin(margin), m_capacity(capacity) {
  if (!(margin >= 0.0 && std::isfinite(margin))) {
    throw InputError("NearCache: margin must be finite and >= 0 m (got " + std::to_string(margin) + ")");
  }
  m_slots.reserve(capacity);
}

MAGVINE_HOT_KERNEL std::size_t CollisionWorld::triangles_within(const Vec3& point, double radius,
                                                                std::span<NearTriangle> out, NearCache& cache,
                                                                double stop_within) const {
  MAGVINE_ASSERT(radius > 0.0 && point.allFinite());
  const Tables& w = m_impl->tables;
  // The last whole answer (every triangle it found fitted its span): again at the same point and radius, for any
  // span it fits.
  if (cache.m_world == m_impl->id && point == cache.m_last_point && radius == cache.m_last_radius &&
      cache.m_last.size() <= out.size()) {
    ++cache.m_hits;
    std::copy(cache.m_last.begin(), cache.m_last.end(), out.begin());
    return cache.m_last.size();
  }
  NearSink sink{w, point, radius, out};
  sink.stop = stop_within;
  // The answer, kept as the last when it is whole (not stopped, nothing dropped from a full span).
  const auto answer = [&] {
    const std::size_t found = sink.finish();
    if (!sink.stopped && found <= out.size()) {
      cache.m_last_point = point;
      cache.m_last_radius = radius;
      cache.m_last.assign(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(found));
    }
    return found;
  };
  // Inside the kept reach, every triangle within the radius of the point is within the reach of the fill point
  // (the triangle inequality; 1e-12 of the coordinates spares the rounding of the two distances).
  const double moved = (point - cache.m_centre).norm();
  const double room = 1e-12 * (point.cwiseAbs().maxCoeff() + cache.m_reach);
  if (cache.m_world == m_impl->id && moved + radius + room <= cache.m_reach) {
    ++cache.m_hits;
    for (const std::uint32_t slot : cache.m_slots) {
      sink.process(slot);
      if (sink.stopped) break;
    }
    return answer();
  }
  // Refill: one walk keeps the triangles within radius + margin of this point and answers this query from them (its
  // sink tests each for the smaller radius). A fill that meets a triangle within stop_within of the point ends there
  // and leaves the cache empty (a line-search trial pushed into the wall is refused whatever else lies near it), as
  // does one with more triangles than the cache holds (its answer is still whole: every triangle within the radius
  // was seen).
  const double reach = radius + cache.m_margin;
  NearSink fill{w, point, reach, {}};
  fill.stop = stop_within;
  cache.m_slots.clear();
  cache.m_world = 0;
  bool fits = true;
  m_impl->bvh->visit_slots(detail::SphereBoxTest(point, reach), [&](std::uint32_t slot) {
    if (!fill.process(slot)) return;
    fits = fits && cache.m_slots.size() < cache.m_capacity;
    if (fits) cache.m_slots.push_back(slot);
    sink.process(slot);
  });
  ++cache.m_fills;
  if (fill.stopped || !fits) {
    cache.m_slots.clear();
  } else {
    cache.m_world = m_impl->id;
    cache.m_centre = point;
    cache.m_reach = reach;
  }
  return answer();
}

namespace {

/// Walks the leaves a ray segment origin + s·dir, s ∈ [0, length()], passes through; `length` is re-read at every
/// node, so a nearest-hit query prunes by its best hit so far.
template <class Query, class Length>
void walk_ray(const detail::TriangleBvh& bvh, const Tables& w, const Vec3& origin, const Vec3& dir, Query& query,
              Length&& length) {
  const Vec3 inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());  // ±∞ for a zero component
  bvh.visit_slots([&](const detail::TriangleBvh::Node& node) { return detail::ray_mask(node, origin, inv, length()); },
                  [&](std::uint32_t slot) {
                    w.ensure(slot);
                    query.process(w.data[slot]);
                  });
}

}  // namespace

std::optional<RayHit> CollisionWorld::ray_cast(const Vec3& origin, const Vec3& direction, double max_distance) const {
  MAGVINE_ASSERT(origin.allFinite() && std::abs(direction.norm() - 1.0) < 1e-9 && max_distance >= 0.0);
  RayQuery query(m_impl->tables, origin, direction, max_distance);
  walk_ray(*m_impl->bvh, m_impl->tables, origin, direction, query, [&] { return query.reach(); });
  return query.result();
}

bool CollisionWorld::segment_crosses(const Vec3& a, const Vec3& b) const {
  const Vec3 d = b - a;
  const double length = d.norm();
  return length > 0.0 && ray_cast(a, d / length, length).has_value();
}

bool CollisionWorld::contains(const Vec3& point) const {
  MAGVINE_ASSERT(point.allFinite());
  const Tables& w = m_impl->tables;
  // Each ray runs past the far side of the bounding box.
  const Vec3 far = (w.box_max - point).cwiseAbs().cwiseMax((w.box_min - point).cwiseAbs());
  const double length = 1.01 * far.norm() + 1e-9;
  int inside = 0;
  int outside = 0;
  int first_vote = 0;  // +1 inside, −1 outside: breaks a 1–1 tie
  for (const Vec3& dir : parity_directions()) {
    ParityQuery query(w, point, dir, length);
    walk_ray(*m_impl->bvh, w, point, dir, query, [length] { return length; });
    if (query.ambiguous()) continue;
    (query.odd() ? inside : outside) += 1;
    if (first_vote == 0) first_vote = query.odd() ? 1 : -1;
    if (inside + outside == kParityVotes) break;
  }
  if (inside != outside) return inside > outside;
  return first_vote > 0;  // no unambiguous ray at all (first_vote = 0) reads as outside
}

std::span<const Vec3> CollisionWorld::parity_directions() {
  // Irregular directions spread over the sphere, none near an axis or a coordinate plane, so axis-aligned or
  // ring-structured meshes (tubes, grids) do not line their edges up with the rays.
  static const std::array<Vec3, 7> kDirections = [] {
    std::array<Vec3, 7> d = {Vec3(0.2674, 0.5131, 0.8153),  Vec3(-0.7412, 0.3381, -0.5799),
                             Vec3(0.4538, -0.8264, 0.3332), Vec3(-0.2191, -0.4433, -0.8693),
                             Vec3(0.9017, 0.2329, -0.3642), Vec3(-0.5563, 0.7797, 0.2874),
                             Vec3(0.1379, -0.2611, 0.9554)};
    for (Vec3& v : d) v.normalize();
    return d;
  }();
  return kDirections;
}

const TriangleMesh& CollisionWorld::mesh() const {
  return m_impl->mesh;
}
const CollisionWorldOptions& CollisionWorld::options() const {
  return m_impl->options;
}
const CollisionWorldStats& CollisionWorld::stats() const {
  return m_impl->stats;
}

}  // namespace magvine::anatomy
