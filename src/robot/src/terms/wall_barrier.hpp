#pragma once
// The wall as a smooth barrier (WallBarrier in rod.hpp; incremental potential contact, Li et al. 2020, eq. 6),
// energy, gradient and Hessian together: per node i and wall triangle t within r_i + d̂ of it, the gap
// g = |x_i − q_t| − r_i stores κ b(g), b(g) = −(g − d̂)² ln(g/d̂) on 0 < g < d̂ (C² at d̂), +∞ at g ≤ 0. The
// triangles are queried from the collision world at every evaluation (no frozen planes). The Hessian keeps
// κ b''(g) n nᵀ and drops the term κ b'(g) ∇²|x − q| of a closest point on an edge or corner, which is negative
// semi-definite (b' < 0): the Newton matrix stays positive semi-definite.

#include <cmath>
#include <limits>
#include <span>
#include <vector>

#include "../rod_system.hpp"
#include "magvine/anatomy/collision_world.hpp"

namespace magvine::robot::detail {

/// b(g) [m²], b'(g) [m] and b''(g) of the barrier at gap g, activation d̂ (0 at and beyond d̂; g must be > 0).
struct BarrierLaw {
  double energy = 0.0;
  double slope = 0.0;
  double curvature = 0.0;
};
inline BarrierLaw barrier_law(double g, double dhat) {
  if (g >= dhat) return {};
  const double d = g - dhat;
  const double l = std::log(g / dhat);
  return {-d * d * l, -2.0 * d * l - d * d / g, -2.0 * l - 4.0 * d / g + d * d / (g * g)};
}

/// The wall's force on a node at gap g: −κ b'(g) ≥ 0 along the unit direction from the wall to the node [N].
inline double barrier_force(const WallBarrier& w, double g) { return -w.stiffness * barrier_law(g, w.activation).slope; }

/// The first size of a thread's buffer for the triangles one node's barrier sums over; it grows to hold all of them
/// (no cap). A cap on the sum made the energy jump as a triangle's rank crossed it: with the nearest 32, a node
/// wedged in the closing end of a generation-4 branch had 40–50 triangles of the 0.3 mm wall within reach, and
/// Newton stalled there with a line search that found no descent (2 of the generation-4 batch's 80 trials,
/// 2026-12-04). Past the carina in bench_growth some nodes have over 128.
inline constexpr std::size_t kBarrierTriangles = 128;

/// How far a node may move before its NearCache walks the BVH again, in d̂: the cache keeps the triangles within
/// r + d̂ + kNearMargin·d̂. Measured on bench_growth (2026-12-04; the carina case, 0.58 M triangles): margins of
/// 0.5, 1, 2, 4 and 8 d̂ took 106, 111, 116, 124 and 146 ms (refills every 20th query at 0.5 d̂, every 50th at 8 d̂:
/// a wider neighbourhood costs more to fill and to test than the walks it spares).
inline constexpr double kNearMargin = 0.5;

/// The triangles within `reach` of node i at x (CollisionWorld::triangles_within), through the node's NearCache when
/// the barrier keeps them; with a cache the query stops at the first triangle within `overlap` (the node's radius):
/// a state whose sphere overlaps the wall is refused whatever else lies near (a line-search trial that pushed the
/// tip 1 mm into the wall found 400–900 triangles within its reach past the carina).
inline std::size_t barrier_triangles(const WallBarrier& w, std::size_t i, const Vec3& x, double reach,
                                     std::span<anatomy::NearTriangle> out, double overlap) {
  if (w.near == nullptr) return w.world->triangles_within(x, reach, out);
  std::vector<anatomy::NearCache>& near = *w.near;
  if (near.size() <= i) near.resize(i + 1, anatomy::NearCache(kNearMargin * w.activation, 1024));
  return w.world->triangles_within(x, reach, out, near[i], overlap);
}

struct WallBarrierTerm {
  /// Calls visit(i, gap, unit normal) for every triangle within reach of node i; false when the node overlaps the
  /// wall (g ≤ 0) or, for a line-search trial moving from the iterate `from`, its centre's path crossed the wall.
  template <class Visit>
  static bool for_each_gap(const RodState& state, const RodState* from, const WallBarrier& w, Visit&& visit) {
    // The thread's own buffer, grown to the most triangles a node has had within reach (no cap: see
    // kBarrierTriangles); a node that finds more than it holds is asked again with room for all.
    thread_local std::vector<anatomy::NearTriangle> near(kBarrierTriangles);
    const std::size_t nodes = state.x.size();
    for (std::size_t i = 1; i < nodes && i < w.radius.size(); ++i) {
      const double r = w.radius[i];
      if (!(r > 0.0)) continue;
      const Vec3& x = state.x[i];
      if (from != nullptr) {
        // A move shorter than r stays inside the wall-free ball of the feasible iterate.
        if ((x - from->x[i]).norm() >= r && w.world->segment_crosses(from->x[i], x)) return false;
      }
      std::size_t found = barrier_triangles(w, i, x, r + w.activation, near, r);
      if (found > near.size()) {
        near.resize(found);
        found = barrier_triangles(w, i, x, r + w.activation, near, r);
      }
      for (const anatomy::NearTriangle& t : std::span(near.data(), found)) {
        const double gap = t.distance - r;
        if (!(gap > 0.0)) return false;
        visit(i, gap, Vec3((x - t.point) / t.distance));
      }
    }
    return true;
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    if (c.constraints == nullptr || !c.constraints->wall) return;
    const WallBarrier& w = *c.constraints->wall;
    double sum = 0.0;
    const bool clear = for_each_gap(c.state, c.from, w, [&](std::size_t i, double gap, const Vec3& n) {
      const BarrierLaw b = barrier_law(gap, w.activation);
      sum += b.energy;
      if (sys != nullptr && b.slope != 0.0) sys->add_gradient(position_slot(static_cast<int>(i)), w.stiffness * b.slope * n);
    });
    energy = clear ? energy + w.stiffness * sum : std::numeric_limits<double>::infinity();
  }

  static void add_hessian(const TermContext& c, System& sys) {
    if (c.constraints == nullptr || !c.constraints->wall) return;
    const WallBarrier& w = *c.constraints->wall;
    for_each_gap(c.state, c.from, w, [&](std::size_t i, double gap, const Vec3& n) {
      const double k = w.stiffness * barrier_law(gap, w.activation).curvature;
      if (k > 0.0) add_block(sys, position_slot(static_cast<int>(i)), position_slot(static_cast<int>(i)), k * n * n.transpose());
    });
  }
};

}  // namespace magvine::robot::detail
