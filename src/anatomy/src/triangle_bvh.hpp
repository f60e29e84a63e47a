#pragma once
/// A 4-wide bounding volume hierarchy over the triangles of a mesh, for the collision world's queries.
///
/// Built with Embree's generic BVH builder (binned SAH, one thread, deterministic) and flattened into two arrays:
/// nodes of four child boxes and a permutation of the triangles in which every leaf is a contiguous run of up to
/// kMaxLeafSize *slots*. Data stored per slot (the collision world's triangle records) is then read in long
/// sequential runs by a query instead of one scattered record per triangle, which is what bounds queries on a
/// 200 k-triangle airway once the records no longer fit in cache.
///
/// Boxes are float, rounded outward from the double vertices, so every test against them is conservative. Walks are
/// templates that inline the caller's box test and leaf visit. Walks are const, allocation-free (a fixed stack) and
/// thread-safe; refit moves the boxes between walks.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy::detail {

class TriangleBvh {
 public:
  /// Triangles per leaf, at most.
  static constexpr unsigned kMaxLeafSize = 8;
  /// Depth bound of the walk stack (Embree's builder stops at depth 32; each level pushes at most 3 siblings).
  static constexpr int kStackSize = 128;

  /// Four child boxes [mesh units] in SoA form, and what each child is: bit 31 set is a leaf of `count` slots from
  /// `first` (bits 0..3 count, bits 4..30 first), clear is an inner node index. Unused children have empty boxes
  /// (lo = +∞, hi = −∞) that every test rejects, and are empty leaves.
  /// Aligned to a cache line (112 bytes padded to 128), so a node is always two lines.
  struct alignas(64) Node {
    std::array<float, 4> lo_x, lo_y, lo_z, hi_x, hi_y, hi_z;
    std::array<std::uint32_t, 4> child;
  };
  static constexpr std::uint32_t kLeafBit = 0x80000000u;
  /// A node whose four children are empty leaves with empty boxes (rejected by every test).
  static Node empty_node();

  /// Builds over `triangles` (indices into `vertices`). Throws InputError when Embree fails, or when the mesh has
  /// more than 2^27 triangles (the slot field of a leaf).
  TriangleBvh(std::span<const Vec3> vertices, std::span<const Triangle> triangles);

  /// Readies refit (once; later calls return at once): each leaf child's distinct corners, from `corners[slot]`,
  /// the slot's triangle's corners as indices into the points refit will be given (slots in leaf order). The only
  /// part of a refit that allocates.
  void prepare_refit(std::span<const std::array<std::uint32_t, 3>> corners);

  /// Recomputes every box bottom-up for moved corners `points` (prepare_refit first), keeping the tree (its nodes,
  /// leaves and slot order), with the build's padding and the outward rounding folded into it (boxes looser than
  /// a build's by at most three float ulps of the largest coordinate); [lo, hi] is the box of every corner.
  void refit(std::span<const Vec3> points, const Vec3& lo, const Vec3& hi);

  /// slot → triangle index: leaves are contiguous runs of slots.
  std::span<const std::uint32_t> order() const { return m_order; }
  std::span<const Node> nodes() const { return m_nodes; }

  /// Visits every leaf whose box passes `test(node, mask_out)`: `test` gets a node and returns a 4-bit mask of the
  /// children to enter (bit k: child k). `visit(first, count)` gets each leaf's slot range.
  template <class Test, class Visit>
  void walk(Test&& test, Visit&& visit) const {
    walk_leaves(test, [&](const Node& node, int k) {
      const std::uint32_t c = node.child[static_cast<std::size_t>(k)];
      visit((c & ~kLeafBit) >> 4, c & 0xFu);
    });
  }

  /// As walk, with `visit(node, k)` for each leaf reached: child k of `node` (its box and slot range).
  template <class Test, class Visit>
  void walk_leaves(Test&& test, Visit&& visit) const {
    std::array<std::uint32_t, kStackSize> stack;
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = m_nodes[stack[--top]];
      unsigned mask = test(node);
      while (mask != 0) {
        const int k = __builtin_ctz(mask);
        mask &= mask - 1;
        const std::uint32_t c = node.child[static_cast<std::size_t>(k)];
        if ((c & kLeafBit) != 0) {
          visit(node, k);
        } else {
          // Fetch both lines of the node now: on a tree far larger than the caches the walk would otherwise wait
          // for each node in turn when it pops it.
          __builtin_prefetch(&m_nodes[c]);
          __builtin_prefetch(reinterpret_cast<const char*>(&m_nodes[c]) + 64);
          stack[top++] = c;
        }
      }
    }
  }

  /// As walk, with `visit(slot)` for every slot of every leaf reached.
  template <class Test, class Visit>
  void visit_slots(Test&& test, Visit&& visit) const {
    walk(test, [&](std::uint32_t first, std::uint32_t count) {
      for (std::uint32_t slot = first; slot < first + count; ++slot) visit(slot);
    });
  }

 private:
  std::vector<Node> m_nodes;  ///< node 0 is the root
  std::vector<std::uint32_t> m_order;
  /// For refit, filled at the first: each leaf child's distinct corner points (a leaf's triangles share most of
  /// their corners, so its box reads each once), listed in m_refit_leaves.
  std::vector<std::uint32_t> m_leaf_points;
  /// A non-empty leaf child for refit: node·4 + child, and its range of m_leaf_points.
  struct RefitLeaf {
    std::uint32_t child, begin, end;
  };
  std::vector<RefitLeaf> m_refit_leaves;
  /// For refit: per node, its place in its parent (parent·4 + child); the root's is unused.
  std::vector<std::uint32_t> m_parent_slot;
};

/// The box of points, kept in six scalars that stay in registers (Eigen's Vec3 minima went through the stack, a
/// third of a refit's vertex pass); the refit's leaf boxes and the collision world's vertex passes.
struct ScalarBox {
  double lo_x = std::numeric_limits<double>::infinity(), lo_y = lo_x, lo_z = lo_x;
  double hi_x = -lo_x, hi_y = -lo_x, hi_z = -lo_x;
  void add(const Vec3& v) {
    lo_x = std::min(lo_x, v.x());
    lo_y = std::min(lo_y, v.y());
    lo_z = std::min(lo_z, v.z());
    hi_x = std::max(hi_x, v.x());
    hi_y = std::max(hi_y, v.y());
    hi_z = std::max(hi_z, v.z());
  }
  std::pair<Vec3, Vec3> box() const { return {Vec3(lo_x, lo_y, lo_z), Vec3(hi_x, hi_y, hi_z)}; }
};

/// One child's box as plain floats [mesh units], kept by callers that re-test a leaf later.
struct ChildBox {
  std::array<float, 3> lo;
  std::array<float, 3> hi;
};

inline ChildBox child_box(const TriangleBvh::Node& node, int k) {
  const auto i = static_cast<std::size_t>(k);
  return {{node.lo_x[i], node.lo_y[i], node.lo_z[i]}, {node.hi_x[i], node.hi_y[i], node.hi_z[i]}};
}

/// Whether the box lies within distance r of point c (squared distance ≤ r²): the one exact sphere–box test.
inline bool sphere_touches(const ChildBox& b, const Vec3& c, double r2) {
  const double dx = std::max({0.0, b.lo[0] - c.x(), c.x() - b.hi[0]});
  const double dy = std::max({0.0, b.lo[1] - c.y(), c.y() - b.hi[1]});
  const double dz = std::max({0.0, b.lo[2] - c.z(), c.z() - b.hi[2]});
  return dx * dx + dy * dy + dz * dz <= r2;
}

/// Children of `node` whose box lies within distance r of point c (squared distance ≤ r²), as a walk mask.
inline unsigned sphere_mask(const TriangleBvh::Node& node, const Vec3& c, double r2) {
  unsigned mask = 0;
  for (int k = 0; k < 4; ++k) mask |= static_cast<unsigned>(sphere_touches(child_box(node, k), c, r2)) << k;
  return mask;
}

/// Children of `node` whose box overlaps the box lo–hi, as a walk mask.
inline unsigned box_mask(const TriangleBvh::Node& node, const Vec3& lo, const Vec3& hi) {
  unsigned mask = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const bool overlap = node.lo_x[k] <= hi.x() && node.hi_x[k] >= lo.x() && node.lo_y[k] <= hi.y() &&
                         node.hi_y[k] >= lo.y() && node.lo_z[k] <= hi.z() && node.hi_z[k] >= lo.z();
    mask |= static_cast<unsigned>(overlap) << k;
  }
  return mask;
}

/// Four floats in one SSE register (GCC/Clang vector extension; elementwise operators, scalars broadcast).
using Float4 = float __attribute__((vector_size(16)));
using Int4 = std::int32_t __attribute__((vector_size(16)));

/// Bit k set where lane k of a vector comparison is true.
inline unsigned lane_mask(const Int4& m) {
  return (m[0] != 0 ? 1u : 0u) | (m[1] != 0 ? 2u : 0u) | (m[2] != 0 ? 4u : 0u) | (m[3] != 0 ? 8u : 0u);
}

inline Float4 load4(const std::array<float, 4>& a) {
  Float4 v;
  std::memcpy(&v, a.data(), sizeof v);
  return v;
}

/// The nearest float at or below (`down`) / above (`up`) a double.
/// The float after f towards −∞ (sign −1) or +∞ (+1): std::nextafter's value for a finite f, by the bits.
inline float float_step(float f, int sign) {
  if (!std::isfinite(f)) return std::nextafter(f, sign * std::numeric_limits<float>::infinity());
  if (f == 0.0F) return sign * std::numeric_limits<float>::denorm_min();
  const auto bits = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>((f > 0.0F) == (sign > 0) ? bits + 1 : bits - 1);
}
inline float float_down(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) <= x ? f : float_step(f, -1);
}
inline float float_up(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) >= x ? f : float_step(f, 1);
}

/// The walk mask of a conservative single-precision test: `maybe` the children it may admit, `sure` those it surely
/// admits; a leaf child admitted only maybe is decided by `exact` (the double-precision mask of that node), so the
/// walk visits exactly the leaves the exact test admits.
template <class Exact>
unsigned refine_mask(const TriangleBvh::Node& node, unsigned maybe, unsigned sure, const Exact& exact) {
  unsigned unsure = maybe & ~sure;
  unsigned mask = maybe;
  unsigned exact_mask = 0;
  bool exact_known = false;  // `exact` is pure: evaluated once, on the first unsure leaf
  while (unsure != 0) {
    const int k = __builtin_ctz(unsure);
    unsure &= unsure - 1;
    if ((node.child[static_cast<std::size_t>(k)] & TriangleBvh::kLeafBit) == 0) continue;
    if (!exact_known) {
      exact_mask = exact();
      exact_known = true;
    }
    if ((exact_mask & (1u << k)) == 0) mask &= ~(1u << k);
  }
  return mask;
}

/// sphere_mask evaluated on four children at once in single precision. The float distances carry a rounding error
/// far below `margin` (1e-6 of the coordinates' size), so children within r − margin are in and beyond r + margin
/// are out; a leaf child in between gets the exact double test, an inner one is entered. The leaves reached are
/// then exactly sphere_mask's, in the same order (entering an extra inner node only costs a test).
class SphereBoxTest {
 public:
  SphereBoxTest(const Vec3& c, double r) : m_c(c), m_r2(r * r) {
    const double margin = 1e-6 * (c.cwiseAbs().maxCoeff() + r);
    m_x = static_cast<float>(c.x());
    m_y = static_cast<float>(c.y());
    m_z = static_cast<float>(c.z());
    // Nothing is sure for a radius below the margin: every admitted leaf then gets the exact test.
    m_in2 = r > margin ? float_down((r - margin) * (r - margin)) : -1.0F;
    m_out2 = float_up((r + margin) * (r + margin));
  }

  unsigned operator()(const TriangleBvh::Node& node) const {
    const Float4 zero = {0.0F, 0.0F, 0.0F, 0.0F};
    const auto gap = [&](const std::array<float, 4>& lo, const std::array<float, 4>& hi, float x) {
      const Float4 below = load4(lo) - x;
      const Float4 above = x - load4(hi);
      const Float4 d = below > above ? below : above;
      return d > zero ? d : zero;
    };
    const Float4 dx = gap(node.lo_x, node.hi_x, m_x);
    const Float4 dy = gap(node.lo_y, node.hi_y, m_y);
    const Float4 dz = gap(node.lo_z, node.hi_z, m_z);
    const Float4 d2 = dx * dx + dy * dy + dz * dz;
    return refine_mask(node, lane_mask(d2 <= m_out2), lane_mask(d2 <= m_in2),
                       [&] { return sphere_mask(node, m_c, m_r2); });
  }

 private:
  Vec3 m_c;
  double m_r2;
  float m_x, m_y, m_z;
  float m_in2, m_out2;
};

/// box_mask evaluated on four children at once in single precision: the query box rounded outward to float
/// admits every child box_mask admits, rounded inward only those it surely admits; a leaf child in between gets
/// the exact test (as for SphereBoxTest).
class BoxBoxTest {
 public:
  BoxBoxTest(const Vec3& lo, const Vec3& hi) : m_lo(lo), m_hi(hi) {
    for (Eigen::Index a = 0; a < 3; ++a) {
      const auto i = static_cast<std::size_t>(a);
      m_outer_lo[i] = float_down(lo[a]);
      m_outer_hi[i] = float_up(hi[a]);
      m_inner_lo[i] = float_up(lo[a]);
      m_inner_hi[i] = float_down(hi[a]);
    }
  }

  unsigned operator()(const TriangleBvh::Node& node) const {
    const auto overlap = [&](const std::array<float, 3>& lo, const std::array<float, 3>& hi) {
      return lane_mask((load4(node.lo_x) <= hi[0]) & (load4(node.hi_x) >= lo[0]) & (load4(node.lo_y) <= hi[1]) &
                       (load4(node.hi_y) >= lo[1]) & (load4(node.lo_z) <= hi[2]) & (load4(node.hi_z) >= lo[2]));
    };
    return refine_mask(node, overlap(m_outer_lo, m_outer_hi), overlap(m_inner_lo, m_inner_hi),
                       [&] { return box_mask(node, m_lo, m_hi); });
  }

 private:
  Vec3 m_lo, m_hi;
  std::array<float, 3> m_outer_lo{}, m_outer_hi{}, m_inner_lo{}, m_inner_hi{};
};

/// Children of `node` whose box the segment o + s·d, s ∈ [0, length], touches, as a walk mask (slab test; `inv`
/// = 1/d per axis, ±∞ for a zero component). The near plane of each slab is chosen by the sign of `inv`, so an
/// empty box (lo = +∞, hi = −∞) gives an entry at +∞ and is rejected.
inline unsigned ray_mask(const TriangleBvh::Node& node, const Vec3& o, const Vec3& inv, double length) {
  unsigned mask = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const std::array<std::pair<float, float>, 3> slab = {std::pair<float, float>{node.lo_x[k], node.hi_x[k]},
                                                         {node.lo_y[k], node.hi_y[k]},
                                                         {node.lo_z[k], node.hi_z[k]}};
    double t0 = 0.0;
    double t1 = length;
    for (Eigen::Index a = 0; a < 3; ++a) {
      const auto& [lo, hi] = slab[static_cast<std::size_t>(a)];
      const bool forward = !std::signbit(inv[a]);
      const double near = ((forward ? lo : hi) - o[a]) * inv[a];
      const double far = ((forward ? hi : lo) - o[a]) * inv[a];
      // A ray in a slab's plane (0·∞ = NaN) must not reject: fmax/fmin ignore NaN.
      t0 = std::fmax(t0, near);
      t1 = std::fmin(t1, far);
    }
    mask |= static_cast<unsigned>(t0 <= t1) << k;
  }
  return mask;
}

}  // namespace magvine::anatomy::detail
