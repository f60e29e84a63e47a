#pragma once
// The rod's energy as a list of terms (rod.hpp): each term's energy, gradient and Hessian live together in one file
// under terms/, and the solver's energy and Hessian are loops over this list. A new term is one new file and one
// entry here. The order is the summation order (kept fixed: it decides the last bits of the energy).

#include <cmath>
#include <tuple>

#include "rod_system.hpp"
#include "terms/anchors.hpp"
#include "terms/bend_twist.hpp"
#include "terms/friction.hpp"
#include "terms/gravity.hpp"
#include "terms/inertia.hpp"
#include "terms/magnetic.hpp"
#include "terms/stretch_shear.hpp"
#include "terms/tip_contact.hpp"
#include "terms/tip_moment.hpp"
#include "terms/wall_barrier.hpp"

namespace magvine::robot::detail {

using RodTerms = std::tuple<StretchShear, BendTwist, Magnetic, InertiaTerm, AnchorTerm, GravityTerm, TipMomentTerm,
                            WallBarrierTerm, FrictionTerm, TipContactTerm>;

/// The energy at load factor λ (c.load); adds its gradient to `sys` when given. Infinite when a joint has folded
/// back on itself: the terms after the first non-finite energy are skipped (the gradient is then incomplete, and
/// every caller rejects the state), so a rejected line-search trial samples no field.
inline double rod_terms_energy(const TermContext& c, System* sys) {
  double energy = 0.0;
  std::apply([&](auto... term) { ((decltype(term)::add_energy(c, energy, sys), std::isfinite(energy)) && ...); },
             RodTerms{});
  return energy;
}

/// The analytic Hessian of rod_terms_energy into sys.diag and sys.sub (zeroed first).
inline void rod_terms_hessian(const TermContext& c, System& sys) {
  for (Mat6& b : sys.diag) b.setZero();
  for (Mat6& b : sys.sub) b.setZero();
  std::apply([&](auto... term) { (decltype(term)::add_hessian(c, sys), ...); }, RodTerms{});
}

}  // namespace magvine::robot::detail
