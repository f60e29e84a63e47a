#pragma once
// Fixed node forces (RodConstraints::forces, NodeForce in rod.hpp: the kinetic friction of a pushed catheter),
// energy and gradient: U = −f·x; no Hessian.

#include "../rod_system.hpp"

namespace magvine::robot::detail {

struct NodeForceTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    for (const NodeForce& f : c.entries(&RodConstraints::forces)) {
      energy -= f.force.dot(c.state.x[static_cast<std::size_t>(f.node)]);
      if (sys != nullptr) sys->add_gradient(position_slot(f.node), -f.force);
    }
  }
  static void add_hessian(const TermContext&, System&) {}
};

}  // namespace magvine::robot::detail
