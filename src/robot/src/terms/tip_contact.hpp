#pragma once
// A contact ahead of the tip (RodConstraints::tip_contact, TipContact in rod.hpp: a needle's tissue), energy,
// gradient and Hessian together: Ψ(d), d = d₀ + (x_N − o)·a, gradient F(d)·a on x_N, Hessian F'(d)·aaᵀ.

#include "../rod_system.hpp"

namespace magvine::robot::detail {

struct TipContactTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    if (c.constraints == nullptr || !c.constraints->tip_contact) return;
    const TipContact& t = *c.constraints->tip_contact;
    const int n = c.edges();
    const ContactLaw l = t.law(tip_contact_depth(t, c.state.x[static_cast<std::size_t>(n)]));
    energy += l.potential;
    // ∇Ψ(d(x)) = Ψ'(d)·a, the chain rule through d = d₀ + (x − o)·a: minus tip_contact_force, the law evaluated once.
    if (sys != nullptr) sys->add_gradient(position_slot(n), l.force * t.axis);
  }

  static void add_hessian(const TermContext& c, System& sys) {
    if (c.constraints == nullptr || !c.constraints->tip_contact) return;
    const TipContact& t = *c.constraints->tip_contact;
    const int n = c.edges();
    const ContactLaw l = t.law(tip_contact_depth(t, c.state.x[static_cast<std::size_t>(n)]));
    add_block(sys, position_slot(n), position_slot(n), l.stiffness * t.axis * t.axis.transpose());
  }
};

}  // namespace magvine::robot::detail
