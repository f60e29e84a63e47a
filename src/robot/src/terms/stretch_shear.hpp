#pragma once
// Stretch and shear of each edge (rod.hpp), energy, gradient and Hessian together:
//   W_j = ½ h vᵀ diag(EA, GA, GA) v,  v = R_jᵀ(x_{j+1} − x_j)/h − e1.

#include "../rod_system.hpp"

namespace magvine::robot::detail {

struct StretchShear {
  static Vec3 stiffness(const TermContext& c) {
    const RodModel& m = c.model;
    return c.h() * Vec3(m.axial_stiffness, m.shear_stiffness, m.shear_stiffness);
  }

  /// Edge j's frame R, edge vector e and strain v = Rᵀe/h − e1.
  struct Edge {
    const Mat3& r;
    Vec3 e;
    Vec3 v;
  };
  static Edge edge(const TermContext& c, int j) {
    const auto ju = static_cast<std::size_t>(j);
    const Mat3& r = c.state.frames[ju];
    const Vec3 e = c.state.x[ju + 1] - c.state.x[ju];
    return {r, e, Vec3(r.transpose() * e / c.h() - Vec3::UnitX())};
  }

  static void add_energy(const TermContext& c, double& energy, System* sys) {
    const double h = c.h();
    const Vec3 ks = stiffness(c);
    for (int j = 0; j < c.edges(); ++j) {
      const auto [r, e, v] = edge(c, j);
      energy += 0.5 * v.dot(ks.cwiseProduct(v));
      if (sys == nullptr) continue;
      add_stress<3>(sys, ks.cwiseProduct(v), {position_slot(j), position_slot(j + 1), rotation_slot(j)},
                    {Mat3(-r.transpose() / h), Mat3(r.transpose() / h), Mat3(r.transpose() * skew(e) / h)});
    }
  }

  /// JᵀKJ plus the axial force's geometric terms (f = Rσ, e the edge): (δx, δφ) couple through [f]/h, and δφ·δφ
  /// through (sym(f eᵀ) − f·e I)/h.
  static void add_hessian(const TermContext& c, System& sys) {
    const double h = c.h();
    const Vec3 ks = stiffness(c);
    for (int j = 0; j < c.edges(); ++j) {
      const auto [r, e, v] = edge(c, j);
      const Vec3 f = r * ks.cwiseProduct(v);
      const Mat3 k_world = r * ks.asDiagonal() * r.transpose() / (h * h);  // H_ee
      const Mat3 jphi = skew(e);                                           // R J_φ h = [e]
      const Mat3 h_ephi = k_world * jphi - skew(f) / h;                    // rows δe, columns δφ
      const Mat3 h_phiphi = jphi.transpose() * k_world * jphi + cross_squared(f, e) / h;
      add_edge_element(sys, j, EdgeVector::difference, k_world, h_ephi, h_phiphi);
    }
  }
};

}  // namespace magvine::robot::detail
