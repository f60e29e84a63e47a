#pragma once
// Shared by the rod and vine tests: the acceptance beam, a state moved along one unknown, and the analytic gradient
// and Hessian of the rod energy against central differences along every unknown (positions by δx, rotations by
// exp([δφ])R).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "magvine/robot/rod.hpp"

namespace magvine::robot::testing {

/// The acceptance beam of issue 4: 60 × 3 × 3 mm NdFeB–Dragon Skin, G = 120 kPa, ρ = 1882 kg/m³, Br = 0.125 T along
/// `magnetisation` (body frame), clamped with tangent +x and normal +y.
constexpr double kBeamLength = 60e-3;
constexpr double kBeamSide = 3e-3;
constexpr double kBeamShearModulus = 120e3;
constexpr double kBeamDensity = 1882.0;
constexpr double kBeamRemanence = 0.125;
inline RodModel acceptance_rod(const Vec3& magnetisation, int edges,
                               double stretch_shear_factor = kNearInextensible) {
  RodModel m = rectangular_rod(kBeamLength, kBeamSide, kBeamSide, kBeamShearModulus, kBeamDensity, kBeamRemanence,
                               magnetisation, edges, stretch_shear_factor);
  m.base_frame = Mat3::Identity();
  return m;
}

/// The state moved along unknown k by d: the position of node k/6 + 1 (k % 6 < 3) or the frame k/6 turned by
/// exp([d e_axis]).
inline RodState moved_state(const RodState& s, Eigen::Index k, double d) {
  RodState t = s;
  const auto block = static_cast<std::size_t>(k / 6);
  const int axis = static_cast<int>(k % 3);
  if ((k % 6) >= 3) {
    t.frames[block] = Eigen::AngleAxisd(d, Vec3::Unit(axis)).toRotationMatrix() * t.frames[block];
  } else {
    t.x[block + 1][axis] += d;
  }
  return t;
}

/// Rebuilds the nodes along the frames (edge j = h R_j e1) plus `noise`·h of random offset: strains stay small, so
/// the stiff stretch and shear terms (EA ≫ EI/L²) do not dominate the gradient and hide errors in the others.
template <class Rng>
void nodes_along_frames(const RodModel& m, RodState& s, double noise, Rng& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = m.length / m.edges;
  for (std::size_t j = 0; j < s.frames.size(); ++j) {
    s.x[j + 1] = s.x[j] + h * s.frames[j].col(0) + noise * h * Vec3(u(rng), u(rng), u(rng));
  }
}

/// Central differences (3e-9 m, 1e-6 rad; a smaller position step lets the energy's round-off through, measured):
/// asserted to 1e-6 relative plus 1e-9 of the
/// largest component (components near zero).
inline void expect_gradient_matches_energy(const RodModel& m, const RodField& field, const RodState& s,
                                           const std::string& label, const RodConstraints* constraints = nullptr) {
  const VecX g = rod_gradient(m, field, s, 1.0, constraints);
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double step = (k % 6) >= 3 ? 1e-6 : 3e-9;
    const auto shifted = [&](double d) { return rod_energy(m, field, moved_state(s, k, d), 1.0, constraints); };
    const double fd = (shifted(step) - shifted(-step)) / (2.0 * step);
    EXPECT_NEAR(g[k], fd, 1e-6 * (std::abs(fd) + g.cwiseAbs().maxCoeff() * 1e-3)) << label << ": unknown " << k;
  }
}

/// The analytic Hessian (what Newton uses) against central differences of the analytic gradient
/// (HessianMethod::finite_differences, itself resting on the gradient checked above). Entries differ by the
/// differences' truncation and round-off: asserted to 1e-5 relative plus 1e-7 of √(H_ii H_jj), the entry's scale
/// from its two unknowns' diagonal stiffnesses. Run twice: as given, and with the stretch and shear stiffness
/// lowered to EI/h², because the near-inextensible rod's stretch terms (~1e6 times the bending ones) set the
/// diagonal and would let errors in the bending and magnetic terms pass (measured: dropping the joints' BCH term or
/// the field curvature passes the first run, fails the second).
inline void expect_hessian_matches_finite_differences(const RodModel& model, const RodField& field, const RodState& s,
                                                      const std::string& label,
                                                      const RodConstraints* constraints = nullptr) {
  RodModel soft = model;
  const double h = model.length / model.edges;
  soft.axial_stiffness = std::max(model.bending_stiffness_2, model.bending_stiffness_3) / (h * h);
  soft.shear_stiffness = soft.axial_stiffness;
  for (const bool stiff : {true, false}) {
    const RodModel& m = stiff ? model : soft;
    const MatX a = rod_hessian(m, field, s, 1.0, HessianMethod::analytic, constraints);
    const MatX f = rod_hessian(m, field, s, 1.0, HessianMethod::finite_differences, constraints);
    double worst = 0.0;
    for (Eigen::Index i = 0; i < a.rows(); ++i) {
      for (Eigen::Index j = 0; j < a.cols(); ++j) {
        const double scale = std::sqrt(std::abs(f(i, i) * f(j, j)));
        const double bound = 1e-5 * std::abs(f(i, j)) + 1e-7 * scale;
        worst = std::max(worst, std::abs(a(i, j) - f(i, j)) / bound);
      EXPECT_NEAR(a(i, j), f(i, j), bound) << label << (stiff ? "" : " (soft stretch)") << ": entry (" << i << ", " << j << ")";
      }
    }
    std::printf("%s (%s stretch): analytic Hessian vs central differences, worst entry at %.3g of its bound\n",
                label.c_str(), stiff ? "stiff" : "soft", worst);
  }
}

}  // namespace magvine::robot::testing
