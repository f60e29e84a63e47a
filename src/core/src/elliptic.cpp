#include "magvine/core/elliptic.hpp"

#include <cmath>
#include <limits>

#include "magvine/core/units.hpp"

namespace magvine {

namespace {
// Bulirsch's stopping tolerance. The AGM converges quadratically, so when |a − b| <= 1e-8·a the result is
// already accurate to about machine precision (fields.md §2: ≤ 1e-15 relative vs 30-digit quadrature).
constexpr double kCelTol = 1e-8;
// Quadratic convergence needs ~6 iterations for any kc in [1e-16, 1e16]; the cap only guards against NaN input.
constexpr int kCelMaxIter = 64;
}  // namespace

double cel_iterate(double a, double b, double p, double c, double s) {
  for (int i = 0; i < kCelMaxIter; ++i) {
    const double g = a * b / p;
    const double c_next = c + s / p;
    s = 2.0 * (s + c * g);
    c = c_next;
    p += g;
    const double a_old = a;
    a += b;
    if (std::abs(a_old - b) <= kCelTol * a_old) break;
    b = 2.0 * std::sqrt(a_old * b);
  }
  return 0.5 * kPi * (s + c * a) / (a * (a + p));
}

double cel(double kc, double p, double c, double s) {
  if (kc == 0.0) return std::numeric_limits<double>::infinity();
  if (p > 0.0) {
    p = std::sqrt(p);
    s /= p;
  } else {
    double f = kc * kc;
    const double q = (1.0 - f) * (s - c * p);
    const double g = 1.0 - p;
    f -= p;
    p = std::sqrt(f / g);
    c = (c - s) / g;
    s = -q / (g * g * p) + c * p;
  }
  const double b = std::abs(kc);
  return cel_iterate(1.0, b, p, c, s);
}

double ellip_k(double m) { return cel(std::sqrt(1.0 - m), 1.0, 1.0, 1.0); }
double ellip_e(double m) { return cel(std::sqrt(1.0 - m), 1.0, 1.0, 1.0 - m); }
double ellip_pi(double n, double m) { return cel(std::sqrt(1.0 - m), 1.0 - n, 1.0, 1.0); }

}  // namespace magvine
