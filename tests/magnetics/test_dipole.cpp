// Point dipole against hand-derived values, the on-axis formula and finite differences.

#include "magvine/magnetics/dipole.hpp"

#include <gtest/gtest.h>

#include <random>

#include "support/compare.hpp"

namespace magvine::magnetics {
namespace {

using test::close;
using test::flat;

TEST(Dipole, HandDerivedValues) {
  // m = 1 A·m² along z. On the axis at 1 m: B = μ0 m/(2π r³) = 2e-7 T; in the equatorial plane: −1e-7 T ẑ.
  const Vec3 m(0, 0, 1);
  EXPECT_TRUE(close(dipole_field(m, Vec3(0, 0, 1)), Vec3(0, 0, 2e-7), 1e-15));
  EXPECT_TRUE(close(dipole_field(m, Vec3(1, 0, 0)), Vec3(0, 0, -1e-7), 1e-15));
  // At r = (1, 0, 1) m: |r| = √2, r̂·m = 1/√2, B = 1e-7/(2√2) (3/√2 r̂ − ẑ) = 1e-7/(2√2) (1.5, 0, 0.5).
  const double k = 1e-7 / (2.0 * std::sqrt(2.0));
  EXPECT_TRUE(close(dipole_field(m, Vec3(1, 0, 1)), Vec3(1.5 * k, 0, 0.5 * k), 1e-14));
  // On-axis gradient ∂B_z/∂z = −3 μ0 m/(2π z⁴) (B falls as z⁻³); transverse −½ of it.
  const Mat3 g = dipole_field_gradient(m, Vec3(0, 0, 2)).g;
  const double gzz = -3.0 * 2e-7 / 16.0;
  EXPECT_NEAR(g(2, 2), gzz, 1e-20);
  EXPECT_NEAR(g(0, 0), -0.5 * gzz, 1e-20);
  EXPECT_NEAR(g(1, 1), -0.5 * gzz, 1e-20);
}

TEST(Dipole, OnAxisFormulaForTheThesisEpm) {
  // |B| = μ0 m/(2π z³) on the axis of m = 970.1 A·m² (thesis 5.6.1).
  const Vec3 m(0, 0, 970.1);
  for (double z : {0.1, 0.16, 0.3}) {
    EXPECT_NEAR(dipole_field(m, Vec3(0, 0, z)).z(), 2e-7 * 970.1 / (z * z * z), 1e-15);
  }
}

TEST(Dipole, GradientMatchesFiniteDifferencesAndIsSymmetricTraceless) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Vec3 m(u(rng) * 100, u(rng) * 100, u(rng) * 100);
    const Vec3 r = Vec3(u(rng), u(rng), u(rng)) * 0.3 + Vec3(0.05, 0, 0);
    const FieldSample s = dipole_field_gradient(m, r);
    EXPECT_TRUE(close(s.b, dipole_field(m, r), 1e-15));
    Mat3 fd;
    const double h = 1e-5 * r.norm();
    for (int j = 0; j < 3; ++j) {
      const Vec3 e = h * Vec3::Unit(j);
      fd.col(j) = (dipole_field(m, r + e) - dipole_field(m, r - e)) / (2 * h);
    }
    EXPECT_TRUE(close(flat(s.g), flat(fd), 1e-8));  // central difference O(h²) ≈ 1e-10, round-off ≈ 1e-11/1e-5
    EXPECT_LE(std::abs(s.g.trace()), 1e-13 * s.g.norm());
    EXPECT_LE((s.g - s.g.transpose()).norm(), 1e-13 * s.g.norm());
  }
}

TEST(Dipole, CurvatureMatchesFiniteDifferencesOfTheGradientAndIsSymmetricTraceless) {
  // Σ_i w_i ∂²B_i/∂x∂x: column j against central differences of Gᵀw along x_j (an independent route: the gradient
  // is itself checked above). The on-axis closed form as a hand value: w·B = w_z μ0 m/(2π z³) on the axis of
  // m = m ẑ, so ∂²/∂z² = 12 w_z μ0 m/(2π z⁵).
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Vec3 m(u(rng) * 100, u(rng) * 100, u(rng) * 100);
    const Vec3 w(u(rng), u(rng), u(rng));
    const Vec3 r = Vec3(u(rng), u(rng), u(rng)) * 0.3 + Vec3(0.05, 0, 0);
    const Mat3 h = dipole_field_curvature(m, r, w);
    Mat3 fd;
    const double step = 1e-5 * r.norm();
    for (int j = 0; j < 3; ++j) {
      const Vec3 e = step * Vec3::Unit(j);
      fd.col(j) = (dipole_field_gradient(m, r + e).g - dipole_field_gradient(m, r - e).g).transpose() * w / (2 * step);
    }
    EXPECT_TRUE(close(flat(h), flat(fd), 1e-8));  // as for the gradient: O(step²) and round-off/step
    EXPECT_LE(std::abs(h.trace()), 1e-12 * h.norm());
    EXPECT_LE((h - h.transpose()).norm(), 1e-13 * h.norm());
  }
  const Mat3 on_axis = dipole_field_curvature(Vec3(0, 0, 1), Vec3(0, 0, 2), Vec3(0, 0, 1));
  EXPECT_NEAR(on_axis(2, 2), 12.0 * 2e-7 / 32.0, 1e-20);
  EXPECT_EQ(dipole_field_curvature(Vec3(1, 2, 3), Vec3::Zero(), Vec3(1, 0, 0)).norm(), 0.0);
}

TEST(Dipole, SingularPointIsZeroNotNan) {
  const FieldSample s = dipole_field_gradient(Vec3(1, 2, 3), Vec3::Zero());
  EXPECT_EQ(s.b.norm(), 0.0);
  EXPECT_EQ(s.g.norm(), 0.0);
  EXPECT_TRUE(dipole_field_gradient(Vec3(1, 2, 3), Vec3(1e-8, 0, 0)).g.allFinite());
}

TEST(Dipole, TheMomentForAFieldDirectionInvertsTheDipoleLaw) {
  // dipole_moment_for_field(r̂, b): the dipole's field at r̂ then points along b, for b along, across and oblique to r̂.
  const Vec3 r = Vec3(0.3, -0.5, 0.8).normalized();
  for (const Vec3& b : {r, Vec3(r.unitOrthogonal()), Vec3(Vec3(1, 2, -1).normalized())}) {
    const Vec3 m = dipole_moment_for_field(r, b);
    const Vec3 field = dipole_field(m, 0.2 * r);
    EXPECT_NEAR(field.normalized().dot(b), 1.0, 1e-12) << b.transpose();
    EXPECT_GE(m.norm(), 0.5 - 1e-12);
  }
}

}  // namespace
}  // namespace magvine::magnetics
