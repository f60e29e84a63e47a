#pragma once
// The wall as a smooth barrier (WallBarrier in rod.hpp; incremental potential contact, Li et al. 2020, eq. 6),
// energy, gradient and Hessian together: per node i and wall triangle t within r_i + d̂ of it, the gap
// g = |x_i − q_t| − r_i stores κ b(g), b(g) = −(g − d̂)² ln(g/d̂) on 0 < g < d̂ (C² at d̂), +∞ at g ≤ 0. The
// triangles are queried from the collision world at every evaluation (no frozen planes). The Hessian keeps
// κ b''(g) n nᵀ and drops the term κ b'(g) ∇²|x − q| of a closest point on an edge or corner, which is negative
// semi-definite (b' < 0): the Newton matrix stays positive semi-definite. A film's node (WallBarrier::flattening)
// replaces r_i by the radius s that minimises the barrier plus its film's energy (section_radius), and its Hessian
// by the Schur complement of s.

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
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

/// Node i's sphere at one state (WallBarrierTerm::for_each_node): the wall's triangles within its reach and the
/// radius s its section takes, with the film's energy and stiffness there.
struct NodeContact {
  std::size_t node = 0;
  Vec3 x = Vec3::Zero();
  std::span<const anatomy::NearTriangle> near;
  double radius = 0.0;  ///< s [m]
  /// Ψ(r − s) [J] and F'(r − s) [N/m]: +∞ where s does not give way (a rigid sphere, one out of contact, or a
  /// section flattened to its core).
  double film_energy = 0.0;
  double film_stiffness = std::numeric_limits<double>::infinity();
  /// The gap of triangle t and its unit normal (from the wall to the node).
  double gap(const anatomy::NearTriangle& t) const { return t.distance - radius; }
  Vec3 normal(const anatomy::NearTriangle& t) const { return (x - t.point) / t.distance; }
};

/// The barrier's push on a sphere of radius s among `near`: B(s) = Σ_t −κ b'(d_t − s) [N] and dB/ds = Σ_t κ b''
/// [N/m] (d_t − s > 0 for every t).
inline std::pair<double, double> barrier_push(const WallBarrier& w, std::span<const anatomy::NearTriangle> near,
                                              double s) {
  double push = 0.0;
  double rate = 0.0;
  for (const anatomy::NearTriangle& t : near) {
    const BarrierLaw b = barrier_law(t.distance - s, w.activation);
    push -= w.stiffness * b.slope;
    rate += w.stiffness * b.curvature;
  }
  return {push, rate};
}

/// The radius s of node i's sphere among `near` (WallBarrier::flattening): r_i for a rigid sphere; for a film's,
/// the root of B(s) = F(r_i − s) on [c·r_i, r_i] (B rises with s, F falls: one root), or c·r_i where the film
/// flattened to its core still does not carry the push. False where the wall is within the rigid part.
inline bool section_radius(const WallBarrier& w, NodeContact& contact) {
  const double r = w.radius[contact.node];
  double nearest = std::numeric_limits<double>::infinity();
  for (const anatomy::NearTriangle& t : contact.near) nearest = std::min(nearest, t.distance);
  contact.radius = r;
  contact.film_energy = 0.0;
  contact.film_stiffness = std::numeric_limits<double>::infinity();
  const double core = rigid_radius(w, contact.node);
  if (!(nearest > core)) return false;
  if (core == r) return true;  // a rigid sphere
  const FlatteningSection& section = w.flattening[contact.node];
  if (nearest >= r + w.activation) return true;  // no triangle within d̂ of the round sphere
  SectionMemo* memo = nullptr;
  if (w.sections != nullptr) {
    if (w.sections->size() <= contact.node) w.sections->resize(contact.node + 1);
    memo = &(*w.sections)[contact.node];
    if (memo->x == contact.x && memo->world == w.world->geometry_id() && memo->radius == r &&
        memo->section == section && memo->core == core && memo->stiffness == w.stiffness &&
        memo->activation == w.activation) {
      contact.radius = memo->s;
      contact.film_energy = memo->energy;
      contact.film_stiffness = memo->film_stiffness;
      return true;
    }
  }
  const auto remember = [&] {
    if (memo != nullptr) {
      *memo = {contact.x, w.world->geometry_id(), r, section, core, w.stiffness, w.activation, contact.radius,
               contact.film_energy, contact.film_stiffness};
    }
    return true;
  };
  double lo = std::max(core, nearest - w.activation);
  double hi = std::min(r, nearest);
  if (const FlatteningLaw at_core = flattening_law(section, r, r - lo);
      barrier_push(w, contact.near, lo).first >= at_core.force) {
    // Flattened to its core (φ(lo) ≥ 0 only at lo = core: B vanishes at nearest − d̂).
    contact.radius = lo;
    contact.film_energy = at_core.energy;
    return remember();
  }
  // Safeguarded Newton on φ(s) = B(s) − F(r − s), rising in s; φ(lo) < 0 ≤ φ(hi).
  double s = 0.5 * (lo + hi);
  for (int k = 0; k < 200; ++k) {
    const auto [push, rate] = barrier_push(w, contact.near, s);
    const FlatteningLaw law = flattening_law(section, r, r - s);
    const double phi = push - law.force;
    (phi > 0.0 ? hi : lo) = s;
    if (std::abs(phi) <= 1e-13 * (push + law.force) || hi - lo <= 1e-15 * r) break;
    const double newton = s - phi / (rate + law.stiffness);
    s = newton > lo && newton < hi ? newton : 0.5 * (lo + hi);
  }
  const FlatteningLaw law = flattening_law(section, r, r - s);
  contact.radius = s;
  contact.film_energy = law.energy;
  contact.film_stiffness = law.stiffness;
  return remember();
}

struct WallBarrierTerm {
  /// Calls visit(NodeContact) for every node with a contact radius; false when a node overlaps the wall (within its
  /// rigid sphere, or within the core of a film's) or, for a line-search trial moving from the iterate `from`, its
  /// centre's path crossed the wall.
  template <class Visit>
  static bool for_each_node(const RodState& state, const RodState* from, const WallBarrier& w, Visit&& visit) {
    // The thread's own buffer, grown to the most triangles a node has had within reach (no cap: see
    // kBarrierTriangles); a node that finds more than it holds is asked again with room for all.
    thread_local std::vector<anatomy::NearTriangle> near(kBarrierTriangles);
    const std::size_t nodes = state.x.size();
    for (std::size_t i = 1; i < nodes && i < w.radius.size(); ++i) {
      const double r = w.radius[i];
      if (!(r > 0.0)) continue;
      const double rigid = rigid_radius(w, i);  // the rigid sphere, or a film's core
      const Vec3& x = state.x[i];
      if (from != nullptr) {
        // A move shorter than that radius stays inside the wall-free ball of the feasible iterate.
        if ((x - from->x[i]).norm() >= rigid && w.world->segment_crosses(from->x[i], x)) return false;
      }
      std::size_t found = barrier_triangles(w, i, x, r + w.activation, near, rigid);
      if (found > near.size()) {
        near.resize(found);
        found = barrier_triangles(w, i, x, r + w.activation, near, rigid);
      }
      NodeContact contact;
      contact.node = i;
      contact.x = x;
      contact.near = std::span<const anatomy::NearTriangle>(near.data(), found);
      if (!section_radius(w, contact)) return false;
      visit(static_cast<const NodeContact&>(contact));
    }
    return true;
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    if (c.constraints == nullptr || !c.constraints->wall) return;
    const WallBarrier& w = *c.constraints->wall;
    double sum = 0.0;
    const bool clear = for_each_node(c.state, c.from, w, [&](const NodeContact& n) {
      sum += n.film_energy;
      for (const anatomy::NearTriangle& t : n.near) {
        const BarrierLaw b = barrier_law(n.gap(t), w.activation);
        sum += w.stiffness * b.energy;
        // The gradient at the minimising s (its own gradient is zero there).
        if (sys != nullptr && b.slope != 0.0) {
          sys->add_gradient(position_slot(static_cast<int>(n.node)), w.stiffness * b.slope * n.normal(t));
        }
      }
    });
    energy = clear ? energy + sum : std::numeric_limits<double>::infinity();
  }

  /// κ b'' n nᵀ per triangle; with a film's s free, the Schur complement of s: − v vᵀ/(Σ κb'' + F'), v = Σ κb'' n
  /// (the barrier and the film in series; positive semi-definite by Cauchy–Schwarz).
  static void add_hessian(const TermContext& c, System& sys) {
    if (c.constraints == nullptr || !c.constraints->wall) return;
    const WallBarrier& w = *c.constraints->wall;
    for_each_node(c.state, c.from, w, [&](const NodeContact& n) {
      Mat3 block = Mat3::Zero();
      Vec3 v = Vec3::Zero();
      double sum = 0.0;
      for (const anatomy::NearTriangle& t : n.near) {
        const double k = w.stiffness * barrier_law(n.gap(t), w.activation).curvature;
        if (!(k > 0.0)) continue;
        const Vec3 normal = n.normal(t);
        block += k * normal * normal.transpose();
        v += k * normal;
        sum += k;
      }
      if (std::isfinite(n.film_stiffness) && sum > 0.0) block -= v * v.transpose() / (sum + n.film_stiffness);
      if (sum > 0.0) add_block(sys, position_slot(static_cast<int>(n.node)), position_slot(static_cast<int>(n.node)), block);
    });
  }
};

}  // namespace magvine::robot::detail
