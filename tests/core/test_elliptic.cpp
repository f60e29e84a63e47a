// Bulirsch's cel against the C++17 special functions (m in [0, 1)) and against direct quadrature (m < 0,
// principal values), as the cylinder formulas need both.

#include "magvine/core/elliptic.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace magvine {
namespace {

// Both sides are computed to ~1e-15 relative; allow a few ulps of accumulated error.
constexpr double kTol = 1e-13;

// Composite Simpson on [0, π/2] with many panels for a smooth integrand: ~1e-14 for these kernels.
template <class F>
double simpson(F f, int n = 20000) {
  const double a = 0.0, b = 0.5 * std::numbers::pi, h = (b - a) / n;
  double s = f(a) + f(b);
  for (int i = 1; i < n; ++i) s += f(a + i * h) * (i % 2 ? 4.0 : 2.0);
  return s * h / 3.0;
}

// K and E from the arithmetic-geometric mean (an independent algorithm): K = π/(2 AGM(1, kc)),
// E = K (1 − Σ 2^(n−1) c_n²) with c_0² = m.
void agm_k_e(double m, double& k, double& e) {
  double a = 1.0, b = std::sqrt(1.0 - m), sum = 0.5 * m, pow2 = 0.5;
  for (int i = 0; i < 40; ++i) {
    const double c = 0.5 * (a - b);
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
    pow2 *= 2.0;
    sum += pow2 * c * c;
  }
  k = std::numbers::pi / (2.0 * a);
  e = k * (1.0 - sum);
}

TEST(Elliptic, MatchesArithmeticGeometricMean) {
  for (double m : {0.0, 0.3, 0.9, 0.999999, 1.0 - 1e-12, -3.0, -1e3}) {
    double k = 0, e = 0;
    agm_k_e(m, k, e);
    EXPECT_NEAR(ellip_k(m), k, kTol * k) << m;
    EXPECT_NEAR(ellip_e(m), e, kTol * e) << m;
  }
}

TEST(Elliptic, MatchesStdForPositiveParameter) {
  // libstdc++'s comp_ellint_* lose ~1e-11 relative as m → 1 (checked against the AGM above), so stop at 0.99.
  for (double m : {0.0, 0.1, 0.5, 0.9, 0.99}) {
    const double k = std::sqrt(m);
    EXPECT_NEAR(ellip_k(m), std::comp_ellint_1(k), kTol * std::comp_ellint_1(k)) << m;
    EXPECT_NEAR(ellip_e(m), std::comp_ellint_2(k), kTol * std::comp_ellint_2(k)) << m;
    for (double n : {-3.0, -0.5, 0.0, 0.3, 0.8}) {
      EXPECT_NEAR(ellip_pi(n, m), std::comp_ellint_3(k, n), kTol * std::comp_ellint_3(k, n)) << m << " " << n;
    }
  }
}

TEST(Elliptic, NegativeParameterMatchesQuadrature) {
  for (double m : {-0.5, -4.0, -100.0, -1e4}) {
    const double kq = simpson([&](double t) { return 1.0 / std::sqrt(1.0 - m * std::sin(t) * std::sin(t)); });
    const double eq = simpson([&](double t) { return std::sqrt(1.0 - m * std::sin(t) * std::sin(t)); });
    const double pq = simpson([&](double t) {
      const double s2 = std::sin(t) * std::sin(t);
      return 1.0 / ((1.0 + 7.0 * s2) * std::sqrt(1.0 - m * s2));
    });
    EXPECT_NEAR(ellip_k(m), kq, 1e-12 * kq) << m;
    EXPECT_NEAR(ellip_e(m), eq, 1e-12 * eq) << m;
    EXPECT_NEAR(ellip_pi(-7.0, m), pq, 1e-12 * pq) << m;
  }
}

TEST(Elliptic, PrincipalValueAndSpecialCases) {
  // cel(kc, p, c, s) with p = 0, s = 0 (the cylinder at r = R) is finite: ∫ c cos²t/(cos²t · sqrt(...)) = c·K.
  const double kc = 0.6;
  EXPECT_NEAR(cel(kc, 0.0, 1.0, 0.0), ellip_k(1.0 - kc * kc), kTol);
  // Known value: K(0) = E(0) = π/2.
  EXPECT_NEAR(ellip_k(0.0), 0.5 * std::numbers::pi, 1e-15);
  EXPECT_NEAR(ellip_e(0.0), 0.5 * std::numbers::pi, 1e-15);
  // kc = 0 diverges: reported as +inf, not NaN.
  EXPECT_TRUE(std::isinf(cel(0.0, 1.0, 1.0, 1.0)));
  // Π(n, m) for n > 1 is the Cauchy principal value; Π(n, 0) = 0 for n > 1 (closed form π/(2√(1−n)) is imaginary,
  // and the real principal value vanishes).
  EXPECT_NEAR(ellip_pi(4.0, 0.0), 0.0, 1e-14);
}

}  // namespace
}  // namespace magvine
