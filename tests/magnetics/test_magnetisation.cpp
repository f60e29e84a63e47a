// Magnetisation laws of robot material against hand calculations (PHYSICS.md §2, thesis 4.4.2 and 5.8.1).

#include "magvine/magnetics/magnetisation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "support/compare.hpp"

namespace magvine::magnetics {
namespace {

using test::close;

TEST(Wrench, TorqueAndForceOnAMoment) {
  // τ = m × B; F = Gᵀ m. m along x in B along z: τ = −m B ŷ.
  FieldSample f;
  f.b = Vec3(0, 0, 0.05);
  f.g << 0.1, 0.2, 0.0, 0.2, -0.3, 0.4, 0.0, 0.4, 0.2;
  const Wrench w = magnetic_wrench(Vec3(2, 0, 0), f);
  EXPECT_TRUE(close(w.torque, Vec3(0, -0.1, 0), 1e-15));
  EXPECT_TRUE(close(w.force, Vec3(0.2, 0.4, 0.0), 1e-15));  // column of G along m: 2·(0.1, 0.2, 0)
}

TEST(Wrench, ForceIsGradientOfEnergyForADipolePair) {
  // Independent check of F = Gᵀm: the force between two coaxial dipoles is 3μ0 m1 m2/(2π d⁴) (attraction).
  const Vec3 m1(0, 0, 970.1), m2(0, 0, 0.05);
  const double d = 0.15;
  const Wrench w = magnetic_wrench(m2, dipole_field_gradient(m1, Vec3(0, 0, d)));
  EXPECT_NEAR(w.force.z(), -3.0 * kMu0 * 970.1 * 0.05 / (2.0 * kPi * std::pow(d, 4)), 1e-12);
}

TEST(HardMagnetic, MomentRotatesWithTheBody) {
  // NdFeB + Ecoflex-30, Br = 0.101 T (thesis), 1 mm³: m = Br V/μ0 = 0.101 · 1e-9 / 1.2566e-6 = 8.037e-5 A·m².
  const Mat3 r = Eigen::AngleAxisd(0.5 * kPi, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 m = hard_magnetic_moment(Vec3(0.101, 0, 0), 1e-9, r);
  EXPECT_TRUE(close(m, Vec3(0, 8.0373e-5, 0), 1e-4));
}

TEST(MagnetTip, MomentOfACylinder) {
  // Ø1 × 2 mm N52 tip, J = 1.48 T: V = 1.5708e-9 m³, m = 1.48 · 1.5708e-9 / μ0 = 1.850e-3 A·m².
  const MagnetTip tip{1e-3, 2e-3, 1.48, Vec3::UnitX()};
  EXPECT_NEAR(tip.moment(Mat3::Identity()).x(), 1.48 * kPi * 0.25e-6 * 2e-3 / kMu0, 1e-12);
  EXPECT_NEAR(tip.moment(Mat3::Identity()).x(), 1.850e-3, 1e-6);
}

TEST(Skin, AxialMagnetisationCancelsOrthogonalKeepsOuterMoment) {
  // Thesis 4.4.2: axial → net 0 with the tail; orthogonal → the outer moment (Br/μ0)·2πRw per unit length.
  // Skin MVR: R = 4 mm, w = 0.2 mm, Br = 0.1 T: 2π·0.004·0.0002 = 5.0265e-6 m² → 0.4000 A·m per metre. The body
  // axis is x (the body-frame convention of magnetisation.hpp).
  const SkinLaw axial{0.004, 0.0002, Vec3(0.1, 0, 0)};
  const SkinLaw orthogonal{0.004, 0.0002, Vec3(0, 0.1, 0)};
  EXPECT_NEAR(axial.moment_per_length(true).norm(), 0.0, 1e-15);
  EXPECT_NEAR(axial.moment_per_length(false).x(), 0.4, 1e-4);
  EXPECT_TRUE(close(SkinLaw{0.004, 0.0002, Vec3(0, 0, 0.1)}.moment_per_length(true), Vec3(0, 0, 0.4), 1e-4));
  EXPECT_TRUE(close(orthogonal.moment_per_length(true), Vec3(0, 0.4, 0), 1e-4));
  EXPECT_NEAR(orthogonal.tail_moment_per_length().norm(), 0.0, 1e-15);
  // 80 mm everted (thesis deflection tests): 0.032 A·m².
  EXPECT_NEAR(orthogonal.moment_per_length(true).norm() * 0.08, 0.032, 1e-5);
}

TEST(Fluid, ThesisLinearLaw) {
  // Eq 5.3: m = σχHV, σ = 0.23, χ = 4999; Ø5 × 50 mm column (V = 9.817e-7 m³) at B = 56 mT:
  // H = 44563 A/m, m = 0.23·4999·44563·9.817e-7 = 50.30 A·m², parallel to B.
  const FluidThesisLaw law;
  const double v = kPi * 0.0025 * 0.0025 * 0.05;
  const Vec3 m = law.moment(Vec3(0.056, 0, 0), v);
  EXPECT_NEAR(m.x(), 0.23 * 4999 * (0.056 / kMu0) * v, 1e-9);
  EXPECT_NEAR(m.x(), 50.30, 0.01);
  EXPECT_NEAR(m.cross(Vec3(0.056, 0, 0)).norm(), 0.0, 1e-15);
}

TEST(Fluid, BoundedLawHandCalculation) {
  // Maxwell-Garnett with χ_p = 4999: β = 4999/5002 = 0.99940, χ_s = 3·0.23β/(1 − 0.23β) = 0.89547.
  const FluidBoundedLaw law;
  const double beta = 4999.0 / 5002.0;
  const double chi_s = 3 * 0.23 * beta / (1 - 0.23 * beta);
  EXPECT_NEAR(law.suspension_susceptibility(), chi_s, 1e-14);
  EXPECT_NEAR(chi_s, 0.8955, 1e-4);
  // Perfectly permeable spheres: μ_s = (1 + 2φ)/(1 − φ) (PHYSICS.md §2).
  FluidBoundedLaw ideal;
  ideal.particle_susceptibility = 1e12;
  EXPECT_NEAR(1.0 + ideal.suspension_susceptibility(), (1 + 2 * 0.23) / (1 - 0.23), 1e-9);

  // Along the axis x (N = 0): M = χ_s H; across (N = 1/2): M = χ_t H, χ_t = χ_s/(1 + χ_s/2). Saturation in the
  // co-energy form (magnetisation.hpp) with χ_ref = χ_s: M = M_s tanh(y/M_s)/y · XH, y = √(χ_s Hᵀ X H), so along
  // the axis M = M_s tanh(χ_s H/M_s) and across M = √(χ_t/χ_s) M_s tanh(√(χ_s χ_t) H/M_s). At 56 mT, far below
  // saturation (M ≈ 4e4 A/m vs φ Ms = 3.9e5 A/m), tanh reduces it by (x²/3) ≈ 0.4 %.
  const double v = 1e-6;
  const double h = 0.056 / kMu0;
  const double ms = 0.23 * 1.7e6;
  const Vec3 m_axial = law.moment(Vec3(0.056, 0, 0), v, Mat3::Identity());
  const double lin_a = chi_s * h;
  EXPECT_NEAR(m_axial.x(), ms * std::tanh(lin_a / ms) * v, 1e-12);
  EXPECT_NEAR(m_axial.x() / (lin_a * v), 1.0, 0.005);
  const Vec3 m_trans = law.moment(Vec3(0, 0, 0.056), v, Mat3::Identity());
  const double chi_t = chi_s / (1 + 0.5 * chi_s);
  EXPECT_NEAR(m_trans.z(), std::sqrt(chi_t / chi_s) * ms * std::tanh(std::sqrt(chi_s * chi_t) * h / ms) * v, 1e-12);
  EXPECT_NEAR(m_trans.z() / (chi_t * h * v), 1.0, 0.005);
  // The bounded moment is ~3 orders of magnitude below the thesis law (PHYSICS.md §2).
  const double ratio = FluidThesisLaw{}.moment(Vec3(0, 0, 0.056), v).z() / m_trans.z();
  EXPECT_GT(ratio, 1000.0);
  EXPECT_LT(ratio, 3000.0);
  // Saturation: at 10 T the moment is bounded by φ·Ms·V.
  EXPECT_LE(law.moment(Vec3(10.0, 0, 0), v, Mat3::Identity()).norm(), ms * v * (1 + 1e-12));
  EXPECT_LE(law.moment(Vec3(3.0, 5.0, -7.0), v, Mat3::Identity()).norm(), ms * v * (1 + 1e-12));
}

TEST(Fluid, TheInducedLawIsAPotential) {
  // M = −de/dB by central differences of the energy density, and d²e/dB² likewise, for an anisotropic law in a weak,
  // a saturating and an oblique field; and the work ∮M·dB round a closed loop in field space vanishes (the law
  // derives from a potential, as the rod's energy minimisation needs). The old "direction of XH, magnitude
  // M_s tanh(|XH|/M_s)" form does work round the same loop: shown for contrast.
  const InducedMagnetisation law = FluidBoundedLaw{}.induced();
  for (const Vec3& b : {Vec3(0.01, 0.02, -0.01), Vec3(0.4, -0.3, 0.5), Vec3(2.0, 1.5, 0.0)}) {
    Vec3 de;
    Mat3 d2e;
    law.energy_density(b, de, &d2e);
    for (int k = 0; k < 3; ++k) {
      const double step = 1e-6 * b.norm();
      Vec3 dp;
      Vec3 dm;
      const double ep = law.energy_density(b + step * Vec3::Unit(k), dp);
      const double em = law.energy_density(b - step * Vec3::Unit(k), dm);
      EXPECT_NEAR((ep - em) / (2.0 * step), de[k], 1e-7 * de.norm()) << b.transpose();
      EXPECT_TRUE(close(Vec3((dp - dm) / (2.0 * step)), Vec3(d2e.col(k)), 1e-6)) << b.transpose();
    }
    EXPECT_TRUE(close(law.magnetisation(b), Vec3(-de), 1e-15));
  }
  // ∮ M·dB round a circle of radius 0.6 T about (0.5, 0.5, 0) in the x–y plane (deep enough to saturate).
  const auto loop_work = [](const auto& magnetisation) {
    const int n = 20000;
    double work = 0.0;
    for (int i = 0; i < n; ++i) {
      const double a0 = 2.0 * kPi * i / n;
      const double a1 = 2.0 * kPi * (i + 1) / n;
      const Vec3 b0(0.5 + 0.6 * std::cos(a0), 0.5 + 0.6 * std::sin(a0), 0.0);
      const Vec3 b1(0.5 + 0.6 * std::cos(a1), 0.5 + 0.6 * std::sin(a1), 0.0);
      work += 0.5 * (magnetisation(b0) + magnetisation(b1)).dot(b1 - b0);
    }
    return work;
  };
  const double potential = loop_work([&](const Vec3& b) { return law.magnetisation(b); });
  const double scale = law.saturation * 0.6;  // |M|·|ΔB| scale of the loop [J/m³]
  EXPECT_LT(std::abs(potential), 1e-6 * scale);
  const double old_form = loop_work([&](const Vec3& b) {
    const Vec3 xh = Vec3(law.axial_susceptibility, law.transverse_susceptibility, law.transverse_susceptibility)
                        .cwiseProduct(b / kMu0);
    return Vec3(law.saturation * std::tanh(xh.norm() / law.saturation) / xh.norm() * xh);
  });
  std::printf("  loop work: co-energy form %.2e J/m3, old form %.2e J/m3 (scale %.2e)\n", potential, old_form, scale);
  EXPECT_GT(std::abs(old_form), 1e-3 * scale);
}

TEST(Fluid, AnisotropyGivesAligningTorqueOnly) {
  // Field at 45° to the column axis x: M is tilted towards the axis (χ larger along it), so τ = m × B ≠ 0 and it
  // turns the column towards B; along the axis or across it the torque vanishes.
  const FluidBoundedLaw law;
  const Vec3 b = Vec3(1, 0, 1).normalized() * 0.05;
  const Vec3 m = law.moment(b, 1e-6, Mat3::Identity());
  const Vec3 tau = m.cross(b);
  EXPECT_GT(tau.norm(), 0.0);
  EXPECT_LT(tau.y(), 0.0);  // rotates e_x towards +z, i.e. about −y
  EXPECT_NEAR(law.moment(Vec3(0.05, 0, 0), 1e-6, Mat3::Identity()).cross(Vec3(0.05, 0, 0)).norm(), 0.0, 1e-18);
  EXPECT_NEAR(law.moment(Vec3(0, 0.05, 0), 1e-6, Mat3::Identity()).cross(Vec3(0, 0.05, 0)).norm(), 0.0, 1e-18);
}

TEST(Magnetorheology, GinderAndDavisYieldStress) {
  // Ginder & Davis (1994): τ_y = √6 φ μ0 M_s^½ H^{3/2} below saturation (∝ H^{3/2}), capped at 0.086 φ μ0 M_s².
  const double h = 20e-3 / kMu0;
  const double tau = magnetorheological_yield_stress(h, 0.23);
  EXPECT_NEAR(tau, std::sqrt(6.0) * 0.23 * kMu0 * std::sqrt(1.7e6) * std::pow(h, 1.5), 1e-9 * tau);
  EXPECT_NEAR(magnetorheological_yield_stress(4.0 * h, 0.23) / tau, 8.0, 1e-9);
  EXPECT_NEAR(magnetorheological_yield_stress(1e9, 0.23), 0.086 * 0.23 * kMu0 * 1.7e6 * 1.7e6, 1e-6);
  EXPECT_NEAR(magnetorheological_yield_stress(-h, 0.23), tau, 1e-12 * tau);  // the field's direction does not matter
}

}  // namespace
}  // namespace magvine::magnetics
