#include "magvine/robot/inflated_beam.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::robot {
namespace {

/// N(φ0) = 2π − 2φ0 + sin 2φ0 and D(φ0) = sin φ0 + (π − φ0) cos φ0, written in ε = π − φ0 as N = 2ε − sin 2ε and
/// D = sin ε − ε cos ε. Both vanish like ε³ at the collapse, so near it (ε < 0.05) their Taylor series replace the
/// formulas, whose cancellation would otherwise lose ~ε⁻³ of the precision (next terms < 2e-11 relative).
struct WrinkleTerms {
  double n;
  double d;
};

/// The terms at ε = π − φ0 directly (no round-off from forming π − φ0 near the collapse).
WrinkleTerms terms_at_collapse_distance(double e) {
  if (e < 0.05) {
    const double e2 = e * e;
    const double e3 = e2 * e;
    return {e3 * (4.0 / 3.0 - e2 * (4.0 / 15.0) + e2 * e2 * (8.0 / 315.0)),
            e3 * (1.0 / 3.0 - e2 / 30.0 + e2 * e2 / 840.0)};
  }
  return {2.0 * e - std::sin(2.0 * e), std::sin(e) - e * std::cos(e)};
}

WrinkleTerms wrinkle_terms(double phi) { return terms_at_collapse_distance(kPi - phi); }

}  // namespace

double wrinkling_moment(double radius, double pressure) {
  return 0.5 * kPi * radius * radius * radius * pressure;
}

double collapse_moment(double radius, double pressure) {
  return kPi * radius * radius * radius * pressure;
}

double wrinkled_moment(double wrinkle_angle, double radius, double pressure) {
  if (wrinkle_angle >= kPi) return collapse_moment(radius, pressure);
  const WrinkleTerms w = wrinkle_terms(wrinkle_angle);
  return pressure * radius * radius * radius * kPi * w.n / (4.0 * w.d);
}

double wrinkle_angle(double moment, double radius, double pressure) {
  const double m = std::abs(moment);
  if (m <= wrinkling_moment(radius, pressure)) return 0.0;
  if (m >= collapse_moment(radius, pressure)) return kPi;
  double lo = 0.0;
  double hi = kPi;
  for (int i = 0; i < 100 && hi - lo > 1e-15; ++i) {
    const double mid = 0.5 * (lo + hi);
    (wrinkled_moment(mid, radius, pressure) < m ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double inflated_curvature(double moment, double radius, double pressure, double bending_stiffness) {
  const double m = std::abs(moment);
  double factor = 1.0;
  if (m >= collapse_moment(radius, pressure)) {
    factor = std::numeric_limits<double>::infinity();
  } else if (m > wrinkling_moment(radius, pressure)) {
    factor = 2.0 * kPi / wrinkle_terms(wrinkle_angle(m, radius, pressure)).n;
  }
  return std::copysign(m * factor / bending_stiffness, moment);
}

double crease_moment(double crease_angle, double radius, double pressure) {
  const double t = std::tan(0.5 * crease_angle);
  return collapse_moment(radius, pressure) * (1.0 + t * t);
}

NormalisedBending normalised_inflated_bending(double curvature) {
  const double k = std::abs(curvature);
  if (k <= 0.5) return {k, 0.5 * k * k, 1.0};
  // Solve D(ε) = π/(2k) for ε ∈ (0, π); D increases with ε (D' = ε sin ε). Newton inside a shrinking bracket.
  const double target = 0.5 * kPi / k;
  double lo = 0.0;
  double hi = kPi;
  double e = target < 0.3 ? std::cbrt(3.0 * target) : 0.5 * kPi;  // D ≈ ε³/3 for small ε
  WrinkleTerms w{};
  for (int i = 0; i < 100; ++i) {
    w = terms_at_collapse_distance(e);
    const double f = w.d - target;
    (f < 0.0 ? lo : hi) = e;
    const double slope = e * std::sin(e);
    double next = slope > 0.0 ? e - f / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const bool done = std::abs(next - e) <= 1e-15 * e;
    e = next;
    if (done || hi - lo <= 1e-15 * hi) break;
  }
  w = terms_at_collapse_distance(e);
  // dm/dk = (dm/dε)/(dk/dε) = (Nε − 4D sin ε)/(2πε); the difference cancels like ε⁶ near the collapse, where its
  // series takes over (next term ~1e-8 relative at ε = 0.05).
  const double e2 = e * e;
  const double stiffness = e < 0.05 ? e2 * e2 * e * (4.0 / 45.0 - 4.0 * e2 / 315.0) / (2.0 * kPi)
                                    : (w.n * e - 4.0 * w.d * std::sin(e)) / (2.0 * kPi * e);
  return {w.n / (4.0 * w.d), 0.25 + kPi / 16.0 * (w.n / (w.d * w.d) + 4.0 * std::cos(e) / w.d), stiffness};
}

TwoStageResult solve_two_stage(const TwoStageVine& vine, const TwoStageLoads& loads, int intervals) {
  const auto positive = [](const char* field, double value) {
    if (!(value > 0.0) || !std::isfinite(value)) {
      throw InputError(std::string("two-stage vine model: ") + field + " = " + std::to_string(value) +
                       " (must be > 0)");
    }
  };
  positive("radius", vine.radius);
  positive("pressure", vine.pressure);
  positive("bending_stiffness", vine.bending_stiffness);
  positive("length", vine.length);
  if (intervals < 2) throw InputError("two-stage vine model: intervals must be >= 2");

  // M_e(x_i) = ∫_x^l q_f(u) u du − x ∫_x^l q_f du + ∫_x^l (q_τ − q_g) du, by cumulative trapezoids from the tip.
  const auto n = static_cast<std::size_t>(intervals);
  const double h = vine.length / intervals;
  const auto eval = [](const std::function<double(double)>& f, double x) { return f ? f(x) : 0.0; };
  std::vector<double> moment(n + 1, 0.0);
  double force_moment = 0.0;  // ∫ q_f u du
  double force = 0.0;         // ∫ q_f du
  double couple = 0.0;        // ∫ (q_τ − q_g) du
  const auto integrand = [&](double x) {
    return std::array<double, 3>{eval(loads.force, x) * x, eval(loads.force, x),
                                 eval(loads.torque, x) - eval(loads.gravity_moment, x)};
  };
  std::array<double, 3> upper = integrand(vine.length);
  for (std::size_t i = n; i-- > 0;) {
    const double x = static_cast<double>(i) * h;
    const std::array<double, 3> lower = integrand(x);
    force_moment += 0.5 * h * (lower[0] + upper[0]);
    force += 0.5 * h * (lower[1] + upper[1]);
    couple += 0.5 * h * (lower[2] + upper[2]);
    moment[i] = force_moment - x * force + couple;
    upper = lower;
  }

  TwoStageResult out;
  out.base_moment = moment[0];
  const double m_w = wrinkling_moment(vine.radius, vine.pressure);
  for (std::size_t i = 0; i <= n; ++i) {
    if (std::abs(moment[i]) >= m_w) out.wrinkled_length = static_cast<double>(i) * h;
  }

  // Stage 1: y(l) = ∫ (l − x) κ(x) dx (trapezoids).
  bool collapsed = false;
  double y = 0.0;
  for (std::size_t i = 0; i <= n && !collapsed; ++i) {
    const double x = static_cast<double>(i) * h;
    const double kappa = inflated_curvature(moment[i], vine.radius, vine.pressure, vine.bending_stiffness);
    collapsed = !std::isfinite(kappa);
    y += (i == 0 || i == n ? 0.5 : 1.0) * h * (vine.length - x) * kappa;
  }
  if (!collapsed && std::abs(y) <= vine.length) {
    out.stage = 1;
    out.tip_deflection = y;
    out.angle = std::asin(y / vine.length);
    return out;
  }

  // Stage 2: the first crease angle where the base moment of the loads falls to the crease moment.
  out.stage = 2;
  const double sign = moment[0] < 0.0 ? -1.0 : 1.0;
  const auto excess = [&](double theta) {
    const double applied = loads.creased_base_moment ? loads.creased_base_moment(sign * theta) : moment[0];
    return sign * applied - crease_moment(theta, vine.radius, vine.pressure);
  };
  constexpr int kScan = 2000;
  double theta = kPi;
  for (int k = 1; k <= kScan; ++k) {
    const double b = kPi * k / (kScan + 1);
    if (excess(b) <= 0.0) {
      double lo = kPi * (k - 1) / (kScan + 1);
      double hi = b;
      for (int i = 0; i < 100; ++i) {
        const double mid = 0.5 * (lo + hi);
        (excess(mid) > 0.0 ? lo : hi) = mid;
      }
      theta = 0.5 * (lo + hi);
      break;
    }
  }
  out.angle = sign * theta;
  out.tip_deflection = vine.length * std::sin(out.angle);
  return out;
}

}  // namespace magvine::robot
