#pragma once
// Stretch and shear of each edge (rod.hpp), energy, gradient and Hessian together:
//   W_j = ½ h_j vᵀ diag(EA, GA, GA) v,  v = R_jᵀ(x_{j+1} − x_j)/h_j − e1,
// except the axial part of the last edge under TipGrowth (rod.hpp), which is the growth law's incremental potential
// W(e) of the extension e = h v_x (tip_growth_law).

#include <algorithm>

#include "../rod_system.hpp"

namespace magvine::robot::detail {

/// Energy, dW/de and d²W/de² of one axial law in the extension e [m].
struct AxialLaw {
  double energy = 0.0;
  double force = 0.0;
  double stiffness = 0.0;
};

/// The growth law on the tip edge (TipGrowth, rod.hpp): W(e) = −F⁺e + ½k e² + ½(100k)(e − limit)₊² for e ≥ 0 when
/// F > 0, −F⁺e + ½K e² for e < 0, K = EA/ℓ the edge's own axial stiffness: C¹ at e = 0, and the plain ½K e² when F ≤ 0
/// (no growth). F⁺ = min(F, k·limit): the tether takes what would grow the tip past it, and a hundred times the growth
/// law's stiffness holds it there against other pulls (the edge's own EA there, 10⁴–10⁶ times k, stalled Newton at
/// the kink).
inline AxialLaw tip_growth_law(const TipGrowth& g, double axial, double e) {
  const double f = std::clamp(g.force, 0.0, g.stiffness * std::max(g.limit, 0.0));
  if (e < 0.0 || f == 0.0) return {-f * e + 0.5 * axial * e * e, -f + axial * e, axial};
  AxialLaw a{-f * e + 0.5 * g.stiffness * e * e, -f + g.stiffness * e, g.stiffness};
  if (e > g.limit) {
    const double tether = 100.0 * g.stiffness;
    const double over = e - g.limit;
    a.energy += 0.5 * tether * over * over;
    a.force += tether * over;
    a.stiffness += tether;
  }
  return a;
}

struct StretchShear {
  /// Edge j's frame R, edge vector e, strain v = Rᵀe/h − e1, and its law: energy W(v), stress σ = dW/dv and the
  /// diagonal of d²W/dv².
  struct Edge {
    const Mat3& r;
    Vec3 e;
    Vec3 v;
    double h;
    double energy;
    Vec3 stress;
    Vec3 stiffness;
  };
  static Edge edge(const TermContext& c, int j) {
    const auto ju = static_cast<std::size_t>(j);
    const RodModel& m = c.model;
    const Mat3& r = c.state.frames[ju];
    const Vec3 e = c.state.x[ju + 1] - c.state.x[ju];
    const double h = c.h(j);
    const Vec3 v = r.transpose() * e / h - Vec3::UnitX();
    const Vec3 ks = h * Vec3(m.axial_stiffness, m.shear_stiffness, m.shear_stiffness);
    Edge out{r, e, v, h, 0.5 * v.dot(ks.cwiseProduct(v)), ks.cwiseProduct(v), ks};
    const TipGrowth* growth = c.constraints != nullptr && c.constraints->growth ? &*c.constraints->growth : nullptr;
    if (growth != nullptr && j == c.edges() - 1) {
      // dW/dv_x = h W'(e) and d²W/dv_x² = h² W''(e) for e = h v_x.
      const AxialLaw a = tip_growth_law(*growth, m.axial_stiffness / h, h * v.x());
      out.energy += a.energy - 0.5 * ks.x() * v.x() * v.x();
      out.stress.x() = h * a.force;
      out.stiffness.x() = h * h * a.stiffness;
    }
    return out;
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    for (int j = 0; j < c.edges(); ++j) {
      const Edge d = edge(c, j);
      energy += d.energy;
      if (sys == nullptr) continue;
      add_stress<3>(sys, d.stress, {position_slot(j), position_slot(j + 1), rotation_slot(j)},
                    {Mat3(-d.r.transpose() / d.h), Mat3(d.r.transpose() / d.h), Mat3(d.r.transpose() * skew(d.e) / d.h)});
    }
  }

  /// JᵀKJ plus the axial force's geometric terms (f = Rσ, e the edge): (δx, δφ) couple through [f]/h, and δφ·δφ
  /// through (sym(f eᵀ) − f·e I)/h.
  static void add_hessian(const TermContext& c, System& sys) {
    for (int j = 0; j < c.edges(); ++j) {
      const Edge d = edge(c, j);
      const double h = d.h;
      const Vec3 f = d.r * d.stress;
      const Mat3 k_world = d.r * d.stiffness.asDiagonal() * d.r.transpose() / (h * h);  // H_ee
      const Mat3 jphi = skew(d.e);                                                      // R J_φ h = [e]
      const Mat3 h_ephi = k_world * jphi - skew(f) / h;                                 // rows δe, columns δφ
      const Mat3 h_phiphi = jphi.transpose() * k_world * jphi + cross_squared(f, d.e) / h;
      add_edge_element(sys, j, EdgeVector::difference, k_world, h_ephi, h_phiphi);
    }
  }
};

}  // namespace magvine::robot::detail
