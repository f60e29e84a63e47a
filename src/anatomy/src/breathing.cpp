#include "magvine/anatomy/breathing.hpp"

#include <algorithm>
#include <cmath>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {

void check_breathing(const BreathingParams& p) {
  if (!(p.period > 0.0 && std::isfinite(p.period))) throw InputError("breathing: period must be > 0");
  if (p.profile < 1 || p.profile > 10) throw InputError("breathing: profile (n of cos^2n) must be in 1..10");
  for (const double a : {p.carina_amplitude, p.lower_amplitude}) {
    if (!(a >= 0.0 && std::isfinite(a))) throw InputError("breathing: amplitudes must be >= 0");
  }
  if (!(p.lower_depth > 0.0 && std::isfinite(p.lower_depth))) throw InputError("breathing: lower_depth must be > 0");
  if (!(std::abs(p.superior.norm() - 1.0) < 1e-9)) throw InputError("breathing: superior must be a unit vector");
  if (!p.entry.allFinite() || !p.carina.allFinite()) throw InputError("breathing: entry and carina must be finite");
  // breathing_rest_point's iteration must contract (and a rising amplitude must not fold the moved airway onto
  // itself): the amplitude may change by less than the distance along ŝ over which it changes, below the carina
  // and above it.
  if (!(std::abs(p.lower_amplitude - p.carina_amplitude) < p.lower_depth)) {
    throw InputError(
        "breathing: |lower_amplitude - carina_amplitude| must be smaller than lower_depth (the moved airway would "
        "fold, or could not be mapped back to its rest shape)");
  }
  const double height = (p.entry - p.carina).dot(p.superior);
  if (height > 0.0 && !(p.carina_amplitude < height)) {
    throw InputError(
        "breathing: carina_amplitude must be smaller than the carina's depth below the entry (the moved "
        "trachea would fold)");
  }
}

double inspiration(const BreathingParams& p, double time) {
  return std::pow(std::cos(kPi * time / p.period), 2 * p.profile);
}

double breathing_amplitude(const BreathingParams& p, const Vec3& x) {
  const double below = (p.carina - x).dot(p.superior);  // depth below the carina [m]
  if (below >= 0.0)
    return p.carina_amplitude + (p.lower_amplitude - p.carina_amplitude) * std::min(1.0, below / p.lower_depth);
  // Above the carina: from the fixed entry (0) to A_c at the carina, by height along ŝ.
  const double height = (p.entry - p.carina).dot(p.superior);
  if (!(height > 0.0)) return p.carina_amplitude;
  return p.carina_amplitude * std::clamp(1.0 + below / height, 0.0, 1.0);
}

Vec3 breathing_displacement(const BreathingParams& p, const Vec3& x, double time) {
  return breathing_displacement(p, breathing_amplitude(p, x), inspiration(p, time));
}

Vec3 breathing_displacement(const BreathingParams& p, double amplitude, double inspiration) {
  return amplitude * (1.0 - inspiration) * p.superior;
}

Vec3 breathing_rest_point(const BreathingParams& p, const Vec3& x, double time) {
  const double phase = inspiration(p, time);
  Vec3 rest = x;
  // Each iteration shrinks the error by the slope times (1 − inspiration), below 1 by check_breathing: 19 iterations
  // with the defaults, ~3000 at a slope of 0.99.
  for (int k = 0; k < 10000; ++k) {
    const Vec3 next = x - breathing_displacement(p, breathing_amplitude(p, rest), phase);
    const double change = (next - rest).norm();
    rest = next;
    if (!(change > 1e-15 * (1.0 + x.norm()))) break;
  }
  return rest;
}

std::vector<double> breathing_amplitudes(const BreathingParams& p, std::span<const Vec3> rest) {
  std::vector<double> out;
  out.reserve(rest.size());
  for (const Vec3& x : rest) out.push_back(breathing_amplitude(p, x));
  return out;
}

void breathing_vertices(const BreathingParams& p, std::span<const Vec3> rest, std::span<const double> amplitudes,
                        double time, std::vector<Vec3>& out) {
  const double phase = inspiration(p, time);
  out.resize(rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) out[i] = rest[i] + breathing_displacement(p, amplitudes[i], phase);
}

}  // namespace magvine::anatomy
