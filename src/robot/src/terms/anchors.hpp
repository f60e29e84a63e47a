#pragma once
// Tangential anchors (RodConstraints::anchors, NodeAnchor in rod.hpp: static friction, the everted vine's no-shear
// condition), energy, gradient and Hessian together: ½k·dᵀ(I − nnᵀ)d, d = x − a, whose gradient is k(I − nnᵀ)d also
// for a normal shorter than 1 (a pinched section's anchor, which holds it partly across the wall too); ½k·|(I − nnᵀ)d|²
// would not be.

#include "../rod_system.hpp"

namespace magvine::robot::detail {

struct AnchorTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    for (const NodeAnchor& a : c.entries(&RodConstraints::anchors)) {
      const Vec3 d = c.state.x[static_cast<std::size_t>(a.node)] - a.anchor;
      const Vec3 tangential = d - a.normal.dot(d) * a.normal;
      energy += 0.5 * a.stiffness * d.dot(tangential);
      if (sys != nullptr) sys->add_gradient(position_slot(a.node), a.stiffness * tangential);
    }
  }

  static void add_hessian(const TermContext& c, System& sys) {
    for (const NodeAnchor& a : c.entries(&RodConstraints::anchors)) {
      add_block(sys, position_slot(a.node), position_slot(a.node),
                  a.stiffness * (Mat3::Identity() - a.normal * a.normal.transpose()));
    }
  }
};

}  // namespace magvine::robot::detail
