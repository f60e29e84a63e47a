#pragma once
// Lagged smoothed Coulomb friction (NodeFriction in rod.hpp; Li et al. 2020, eqs. 14–16), energy, gradient and
// Hessian together: D = μλ f0(|u|), u = P(x − x_ref), f0(y) = y for y ≥ ε and −y³/(3ε²) + y²/ε + ε/3 below.
// The Hessian is the exact one, positive semi-definite: μλ[(2/ε − y/ε²)P − (y/ε²)ûûᵀ] below ε, μλ(P − ûûᵀ)/y
// past it (P = I − nnᵀ − ffᵀ, f the free direction or zero).

#include "../rod_system.hpp"

namespace magvine::robot::detail {

/// f0(y) and f1(y)/y = f0'(y)/y of the friction mollifier for slip ε.
struct FrictionLaw {
  double energy = 0.0;     ///< f0(y) [m]
  double force_per = 0.0;  ///< f1(y)/y [1/m]
  double tangent = 0.0;    ///< the Hessian's coefficient along û minus its coefficient across, f1' − f1/y [1/m]
};
inline FrictionLaw friction_law(double y, double eps) {
  if (y >= eps) return {y, 1.0 / y, -1.0 / y};
  return {-y * y * y / (3.0 * eps * eps) + y * y / eps + eps / 3.0, 2.0 / eps - y / (eps * eps), -y / (eps * eps)};
}

struct FrictionTerm {
  struct Slip {
    Vec3 u;        ///< tangential slip
    double y;      ///< |u|
    double scale;  ///< μλ
  };
  static Slip slip(const TermContext& c, const NodeFriction& f) {
    const Vec3 u = friction_slip(f, c.state.x[static_cast<std::size_t>(f.node)]);
    return {u, u.norm(), f.coefficient * f.normal_force};
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    if (c.constraints == nullptr) return;
    for (const NodeFriction& f : c.constraints->friction) {
      const Slip s = slip(c, f);
      const FrictionLaw law = friction_law(s.y, f.slip);
      energy += s.scale * law.energy;
      if (sys != nullptr) sys->add_gradient(position_slot(f.node), s.scale * law.force_per * s.u);
    }
  }

  static void add_hessian(const TermContext& c, System& sys) {
    if (c.constraints == nullptr) return;
    for (const NodeFriction& f : c.constraints->friction) {
      const Slip s = slip(c, f);
      const FrictionLaw law = friction_law(s.y, f.slip);
      const Mat3 p = Mat3::Identity() - f.normal * f.normal.transpose() - f.free * f.free.transpose();
      Mat3 h = law.force_per * p;
      if (s.y > 0.0) h += law.tangent * (s.u / s.y) * (s.u / s.y).transpose();
      add_block(sys, position_slot(f.node), position_slot(f.node), s.scale * h);
    }
  }
};

}  // namespace magvine::robot::detail
