#pragma once
// A tip moment M (world frame) on the last edge (rod.hpp), energy, gradient and Hessian together: U = −λM·φ with
// φ = log(R_N R_baseᵀ), the rotation vector from the clamp (exact for moments about a fixed axis, e.g. planar bending).

#include <cmath>

#include <Eigen/Geometry>

#include "../rod_system.hpp"

namespace magvine::robot::detail {

/// Gradient of the tip moment's potential −λM·φ in δφ of the last edge: −λ J_l⁻¹(φ)ᵀM with
/// J_l⁻¹(φ) = I − ½[φ] + (1/θ² − (1 + cos θ)/(2θ sin θ))[φ]²; also returns φ.
inline Vec3 tip_moment_gradient(const Mat3& last, const Mat3& base, const Vec3& moment, double load, Vec3& phi) {
  const Eigen::AngleAxisd turn(last * base.transpose());
  phi = turn.angle() * turn.axis();
  const double theta = turn.angle();
  const double c = theta < 1e-4 ? 1.0 / 12.0 + theta * theta / 720.0
                                 : 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  const Mat3 inverse_jacobian = Mat3::Identity() - 0.5 * skew(phi) + c * skew(phi) * skew(phi);
  return -load * inverse_jacobian.transpose() * moment;
}

struct TipMomentTerm {
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    const RodModel& m = c.model;
    if (m.tip_moment.isZero()) return;
    Vec3 phi;
    const Vec3 g = tip_moment_gradient(c.state.frames.back(), m.base_frame, m.tip_moment, c.load, phi);
    energy -= c.load * m.tip_moment.dot(phi);
    if (sys != nullptr) sys->add_gradient(rotation_slot(c.edges() - 1), g);
  }

  /// Central differences of its one-block gradient.
  static void add_hessian(const TermContext& c, System& sys) {
    const RodModel& m = c.model;
    if (m.tip_moment.isZero()) return;
    const Mat3 r0 = c.state.frames.back();
    add_block(sys, rotation_slot(c.edges() - 1), rotation_slot(c.edges() - 1),
                local_rotation_hessian([&](const Vec3& phi) {
                  Vec3 rotation;
                  return tip_moment_gradient(exp_rotation(phi) * r0, m.base_frame, m.tip_moment, c.load, rotation);
                }));
  }
};

}  // namespace magvine::robot::detail
