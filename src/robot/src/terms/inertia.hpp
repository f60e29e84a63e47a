#pragma once
// The inertia of one backward-Euler step written as an incremental potential (step_rod_dynamics), energy, gradient
// and Hessian together: with predictions x̃_i = x_i + Δt v_i and R̃_j = exp(Δt [w_j]) R_j the step minimises
//   E + Σ m_i|x_i − x̃_i|²/(2Δt²) + Σ J_j|θ_j|²/(2Δt²),  θ_j = vee((R_j R̃_jᵀ − R̃_j R_jᵀ)/2)
// (the rotation from the prediction, sin θ·axis).

#include "../rod_system.hpp"

namespace magvine::robot::detail {

/// Gradient of the rotational inertia term ½ k J |θ|², θ = vee(skew(P)), P = R R̃ᵀ, in δφ (R ← exp([δφ])R).
inline Vec3 rotational_inertia_gradient(const Mat3& p, double k_j) {
  return k_j * (0.5 * (p.trace() * Mat3::Identity() - p)).transpose() * skew_axis(p);
}

struct InertiaTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    const Inertia* inertia = c.inertia;
    if (inertia == nullptr) return;
    const int n = c.edges();
    const double k = 1.0 / (inertia->dt * inertia->dt);
    for (int i = 1; i <= n; ++i) {
      const auto iu = static_cast<std::size_t>(i);
      const Vec3 d = c.state.x[iu] - inertia->x[iu];
      energy += 0.5 * k * inertia->mass[iu] * d.squaredNorm();
      if (sys != nullptr) sys->add_gradient(position_slot(i), k * inertia->mass[iu] * d);
    }
    for (int j = 0; j < n; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const Mat3 p = c.state.frames[ju] * inertia->frames[ju].transpose();
      const Vec3 theta = skew_axis(p);
      energy += 0.5 * k * inertia->rotational * theta.squaredNorm();
      if (sys != nullptr) sys->add_gradient(rotation_slot(j), rotational_inertia_gradient(p, k * inertia->rotational));
    }
  }

  /// The lumped masses' k·m_i I; the rotational part by central differences of its one-block gradient.
  static void add_hessian(const TermContext& c, System& sys) {
    const Inertia* inertia = c.inertia;
    if (inertia == nullptr) return;
    const int n = c.edges();
    const double k = 1.0 / (inertia->dt * inertia->dt);
    for (int i = 1; i <= n; ++i) {
      const Slot si = position_slot(i);
      add_block(sys, si, si, k * inertia->mass[static_cast<std::size_t>(i)] * Mat3::Identity());
    }
    for (int j = 0; j < n; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      const Mat3 p0 = c.state.frames[ju] * inertia->frames[ju].transpose();
      add_block(sys, rotation_slot(j), rotation_slot(j), local_rotation_hessian([&](const Vec3& phi) {
                    return rotational_inertia_gradient(exp_rotation(phi) * p0, k * inertia->rotational);
                  }));
    }
  }
};

}  // namespace magvine::robot::detail
