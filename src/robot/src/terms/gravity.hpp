#pragma once
// Gravity on lumped node masses (ρA over half of each adjacent edge, rod_system.hpp) and the tip force on x_N (rod.hpp), energy and
// gradient: U = −λ Σ f_i·x_i; no Hessian.

#include "../rod_system.hpp"

namespace magvine::robot::detail {

struct GravityTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    const RodModel& m = c.model;
    const int n = c.edges();
    for (int i = 1; i <= n; ++i) {
      const double mass = lumped_mass(m, static_cast<std::size_t>(i));
      Vec3 f = c.load * mass * m.gravity;
      if (i == n) f += c.load * m.tip_force;
      energy -= f.dot(c.state.x[static_cast<std::size_t>(i)]);
      if (sys != nullptr) sys->add_gradient(position_slot(i), -f);
    }
  }
  static void add_hessian(const TermContext&, System&) {}
};

}  // namespace magvine::robot::detail
