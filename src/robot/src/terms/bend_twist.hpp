#pragma once
// Bending and twist at each joint (rod.hpp), energy, gradient and Hessian together:
//   W_j = ℓ w(ω − ω_rest),  ω = 2 vee(Q − Qᵀ)/((1 + tr Q) ℓ),  Q = R_{j−1}ᵀ R_j,
// ℓ = h between edges and h/2 between the clamp frame and the first edge; w the linear law ½ωᵀdiag(GJ, EI_2, EI_3)ω
// of a rod, or for a vine the inflated-beam law (InflatedBending: wrinkling to the collapse, the flat film, the
// crease hinge of eq 4.13 as the same law's joint form). The pressure enters the rod's energy only here, through
// the collapse moment πR³P of that law.

#include <cmath>
#include <limits>

#include "../rod_system.hpp"
#include "magvine/robot/inflated_beam.hpp"

namespace magvine::robot::detail {

/// ω = 2 tan(ψ/2)·axis/ℓ of the joint rotation Q (the Gibbs vector over ℓ/2).
inline Vec3 joint_strain(const Mat3& q, double ell) { return 4.0 * skew_axis(q) / ((1.0 + q.trace()) * ell); }

/// The rest strain of joint j (RodModel::rest_strain).
inline Vec3 rest_strain(const RodModel& m, int j) {
  return m.rest_strain.empty() ? Vec3::Zero() : m.rest_strain[static_cast<std::size_t>(j)];
}

/// The stored energy of one joint of length ℓ at curvature-twist ω (body frame of the joint's first edge), and
/// `stress` = dW/dω: the linear law of a rod, or the inflated-beam law of a vine (InflatedBending).
inline double joint_energy(const RodModel& m, double ell, const Vec3& omega, Vec3& stress) {
  if (!m.inflated) {
    const Vec3 k = ell * Vec3(m.torsional_stiffness, m.bending_stiffness_2, m.bending_stiffness_3);
    stress = k.cwiseProduct(omega);
    return 0.5 * omega.dot(stress);
  }
  const InflatedBending& law = *m.inflated;
  const double ei = m.bending_stiffness_3;
  const Vec3 bend(0.0, omega.y(), omega.z());
  const double kappa = bend.norm();
  double energy = 0.5 * ell * m.torsional_stiffness * omega.x() * omega.x();
  stress = Vec3(ell * m.torsional_stiffness * omega.x(), 0.0, 0.0);
  // dW/dκ / κ for each term, so the linear range needs no division by κ.
  double per_kappa = ell * law.flat_bending_stiffness;
  energy += 0.5 * ell * law.flat_bending_stiffness * kappa * kappa;
  const double collapse = collapse_moment(law.radius, law.pressure);
  if (collapse > 0.0) {
    const double k = kappa * ei / collapse;
    const NormalisedBending w = normalised_inflated_bending(k);
    energy += ell * collapse * collapse / ei * w.energy;
    per_kappa += k <= 0.5 ? ell * ei : ell * collapse * w.moment / kappa;
  }
  stress += per_kappa * bend;
  return energy;
}

/// d²W/dω² of joint_energy.
inline Mat3 joint_stiffness(const RodModel& m, double ell, const Vec3& omega) {
  if (!m.inflated) return (ell * Vec3(m.torsional_stiffness, m.bending_stiffness_2, m.bending_stiffness_3)).asDiagonal();
  const InflatedBending& law = *m.inflated;
  const double ei = m.bending_stiffness_3;
  const Vec3 bend(0.0, omega.y(), omega.z());
  const double kappa = bend.norm();
  Mat3 k = Mat3::Zero();
  k(0, 0) = ell * m.torsional_stiffness;
  double per_kappa = ell * law.flat_bending_stiffness;
  double slope = 0.0;  // d(per_kappa)/dκ / κ
  const double collapse = collapse_moment(law.radius, law.pressure);
  if (collapse > 0.0) {
    const double kn = kappa * ei / collapse;
    if (kn <= 0.5) {
      per_kappa += ell * ei;
    } else {
      const NormalisedBending w = normalised_inflated_bending(kn);
      per_kappa += ell * collapse * w.moment / kappa;
      slope = ell * (ei * w.stiffness - collapse * w.moment / kappa) / (kappa * kappa);
    }
  }
  k(1, 1) = per_kappa;
  k(2, 2) = per_kappa;
  return k + slope * bend * bend.transpose();
}

/// The first frame of joint j (the clamp frame or edge j − 1's; the second is edge j's) and its length ℓ (h/2 at the
/// clamp, else half of each edge it joins: h between edges of h).
inline const Mat3& joint_first_frame(const RodModel& m, const RodState& s, int j) {
  return j == 0 ? m.base_frame : s.frames[static_cast<std::size_t>(j) - 1];
}
inline double joint_length(const RodModel& m, int j) {
  return j == 0 ? 0.5 * edge_length(m, 0) : 0.5 * (edge_length(m, j - 1) + edge_length(m, j));
}

struct BendTwist {
  /// A joint folded back on itself makes the energy infinite (and the gradient incomplete; rod_terms_energy then
  /// stops).
  static void add_energy(const TermContext& c, double& energy, System* sys) {
    for (int j = 0; j < c.edges(); ++j) {
      const Mat3& ra = joint_first_frame(c.model, c.state, j);
      const Mat3& rb = c.state.frames[static_cast<std::size_t>(j)];
      const double ell = joint_length(c.model, j);
      const Mat3 q = ra.transpose() * rb;
      const double cq = 1.0 + q.trace();  // 2(1 + cos ψ)
      if (!(cq > 1e-12)) {
        energy = std::numeric_limits<double>::infinity();
        return;
      }
      const Vec3 half_sine = skew_axis(q);  // sin ψ · axis
      const Vec3 omega = joint_strain(q, ell);
      Vec3 stress;
      energy += joint_energy(c.model, ell, omega - rest_strain(c.model, j), stress);
      if (sys == nullptr) continue;
      // dω/dδφ_b = (2/ℓ)[(tr Q·I − Q)/c + 4 s sᵀ/c²] R_aᵀ, and the opposite for δφ_a.
      const Mat3 d = (2.0 / ell) *
                     ((q.trace() * Mat3::Identity() - q) / cq + 4.0 * half_sine * half_sine.transpose() / (cq * cq)) *
                     ra.transpose();
      add_stress<2>(sys, stress, {Slot{j == 0 ? -1 : j - 1, 3}, rotation_slot(j)}, {Mat3(-d), d});
    }
  }

  /// With Q = R_aᵀR_b and its Gibbs vector b = ℓω/2, a left turn u (body of a) gives
  ///   ω = ω0 + J u/ℓ + (bᵀu) J u/(2ℓ),  J = I − [b] + bbᵀ,
  /// so H̃ = R_a[JᵀKJ/ℓ² + (b vᵀ + v bᵀ)/(2ℓ)]R_aᵀ, v = Jᵀσ, for either frame, and H_ab = −H̃ + [g]/2 (the
  /// Baker–Campbell–Hausdorff term of exp(−[δφ_a])exp([δφ_b]), g the joint's gradient in δφ_b).
  static void add_hessian(const TermContext& c, System& sys) {
    for (int j = 0; j < c.edges(); ++j) {
      const Mat3& ra = joint_first_frame(c.model, c.state, j);
      const Mat3& rb = c.state.frames[static_cast<std::size_t>(j)];
      const double ell = joint_length(c.model, j);
      const Mat3 q = ra.transpose() * rb;
      const Vec3 omega = joint_strain(q, ell);
      const Vec3 strain = omega - rest_strain(c.model, j);
      Vec3 stress;
      joint_energy(c.model, ell, strain, stress);
      const Vec3 b = 0.5 * ell * omega;
      const Mat3 jac = Mat3::Identity() - skew(b) + b * b.transpose();
      const Vec3 vv = jac.transpose() * stress;
      const Mat3 local = jac.transpose() * joint_stiffness(c.model, ell, strain) * jac / (ell * ell) +
                         (b * vv.transpose() + vv * b.transpose()) / (2.0 * ell);
      const Mat3 tilde = ra * local * ra.transpose();
      const Slot sb = rotation_slot(j);
      add_block(sys, sb, sb, tilde);
      if (j == 0) continue;
      const Slot sa = rotation_slot(j - 1);
      const Vec3 g = ra * vv / ell;  // the joint's gradient in δφ_b
      add_block(sys, sa, sa, tilde);
      add_block(sys, sb, sa, -tilde - 0.5 * skew(g));  // H_ba = H_abᵀ
    }
  }
};

}  // namespace magvine::robot::detail
