// Magnetisation laws of robot material against hand calculations (PHYSICS.md §2, thesis 4.4.2 and 5.8.1).

#include "magvine/magnetics/magnetisation.hpp"

#include <gtest/gtest.h>

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
  const MagnetTip tip{1e-3, 2e-3, 1.48, Vec3::UnitZ()};
  EXPECT_NEAR(tip.moment(Mat3::Identity()).z(), 1.48 * kPi * 0.25e-6 * 2e-3 / kMu0, 1e-12);
  EXPECT_NEAR(tip.moment(Mat3::Identity()).z(), 1.850e-3, 1e-6);
}

TEST(Skin, AxialMagnetisationCancelsOrthogonalKeepsOuterMoment) {
  // Thesis 4.4.2: axial → net 0 with the tail; orthogonal → the outer moment (Br/μ0)·2πRw per unit length.
  // Skin MVR: R = 4 mm, w = 0.2 mm, Br = 0.1 T: 2π·0.004·0.0002 = 5.0265e-6 m² → 0.4000 A·m per metre.
  const SkinLaw axial{0.004, 0.0002, Vec3(0, 0, 0.1)};
  const SkinLaw orthogonal{0.004, 0.0002, Vec3(0, 0.1, 0)};
  EXPECT_NEAR(axial.moment_per_length(true).norm(), 0.0, 1e-15);
  EXPECT_NEAR(axial.moment_per_length(false).z(), 0.4, 1e-4);
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

  // Along the axis (N = 0): M = χ_s H; across (N = 1/2): M = χ_s/(1 + χ_s/2) H. At 56 mT, far below
  // saturation (M ≈ 4e4 A/m vs φ Ms = 3.9e5 A/m), tanh reduces it by (x²/3) ≈ 0.4 %.
  const double v = 1e-6;
  const double h = 0.056 / kMu0;
  const double ms = 0.23 * 1.7e6;
  const Vec3 m_axial = law.moment(Vec3(0, 0, 0.056), v, Mat3::Identity());
  const double lin_a = chi_s * h;
  EXPECT_NEAR(m_axial.z(), ms * std::tanh(lin_a / ms) * v, 1e-12);
  EXPECT_NEAR(m_axial.z() / (lin_a * v), 1.0, 0.005);
  const Vec3 m_trans = law.moment(Vec3(0.056, 0, 0), v, Mat3::Identity());
  const double lin_t = chi_s / (1 + 0.5 * chi_s) * h;
  EXPECT_NEAR(m_trans.x(), ms * std::tanh(lin_t / ms) * v, 1e-12);
  // The bounded moment is ~3 orders of magnitude below the thesis law (PHYSICS.md §2).
  const double ratio = FluidThesisLaw{}.moment(Vec3(0.056, 0, 0), v).x() / m_trans.x();
  EXPECT_GT(ratio, 1000.0);
  EXPECT_LT(ratio, 3000.0);
  // Saturation: at 10 T the moment is bounded by φ·Ms·V.
  EXPECT_LE(law.moment(Vec3(0, 0, 10.0), v, Mat3::Identity()).norm(), ms * v * (1 + 1e-12));
}

TEST(Fluid, AnisotropyGivesAligningTorqueOnly) {
  // Field at 45° to the column axis: M is tilted towards the axis (χ larger along it), so τ = m × B ≠ 0 and it
  // turns the column towards B; along the axis or across it the torque vanishes.
  const FluidBoundedLaw law;
  const Vec3 b = Vec3(1, 0, 1).normalized() * 0.05;
  const Vec3 m = law.moment(b, 1e-6, Mat3::Identity());
  const Vec3 tau = m.cross(b);
  EXPECT_GT(tau.norm(), 0.0);
  EXPECT_GT(tau.y(), 0.0);  // rotates e_z towards +x, i.e. about +y
  EXPECT_NEAR(law.moment(Vec3(0, 0, 0.05), 1e-6, Mat3::Identity()).cross(Vec3(0, 0, 0.05)).norm(), 0.0, 1e-18);
}

}  // namespace
}  // namespace magvine::magnetics
