#pragma once
// Wall contacts (RodConstraints::contacts, NodeContact in rod.hpp), frozen as planes for one solve, energy, gradient
// and Hessian together: depth d = r − n·(x − p); energy ½k d² (+ kε²/6) for d ≥ ε, none for d ≤ −ε, and the cubic
// k(d + ε)³/(12ε) between them (stiffness rising linearly from 0 to k: a C² energy).

#include "../rod_system.hpp"

namespace magvine::robot::detail {

/// Energy, force (−dE/d(depth) along the normal, ≥ 0) and stiffness of one wall contact at node position x.
struct ContactLaw {
  double energy = 0.0;
  double force = 0.0;
  double stiffness = 0.0;
};
inline ContactLaw contact_law(const NodeContact& c, const Vec3& x) {
  const double depth = c.radius - c.normal.dot(x - c.point);
  const double k = c.stiffness;
  const double e = c.smoothing;
  if (depth >= e) {
    // ½k d² (+ the smoothing zone's offset kε²/6, which keeps the energy continuous).
    return {0.5 * k * depth * depth + k * e * e / 6.0, k * depth, k};
  }
  if (depth <= -e) return {};
  // Cubic blend on |d| < ε: stiffness rising linearly from 0 at d = −ε to k at d = ε (C² energy).
  const double s = depth + e;
  return {k * s * s * s / (12.0 * e), k * s * s / (4.0 * e), k * s / (2.0 * e)};
}

struct WallContactTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    for (const NodeContact& k : c.entries(&RodConstraints::contacts)) {
      const ContactLaw law = contact_law(k, c.state.x[static_cast<std::size_t>(k.node)]);
      energy += law.energy;
      if (sys != nullptr && law.force > 0.0) sys->add_gradient(position_slot(k.node), -law.force * k.normal);
    }
  }

  static void add_hessian(const TermContext& c, System& sys) {
    for (const NodeContact& k : c.entries(&RodConstraints::contacts)) {
      const ContactLaw law = contact_law(k, c.state.x[static_cast<std::size_t>(k.node)]);
      if (law.stiffness > 0.0) {
        add_block(sys, position_slot(k.node), position_slot(k.node), law.stiffness * k.normal * k.normal.transpose());
      }
    }
  }
};

}  // namespace magvine::robot::detail
