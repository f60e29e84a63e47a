#pragma once
// Shared by the design optimisers (design.cpp, bayesian.cpp, least_squares.cpp) and calibration.cpp. Private to the
// design module.

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <unsupported/Eigen/LevenbergMarquardt>
#include <utility>
#include <vector>

#include "magvine/core/stopwatch.hpp"
#include "magvine/design/design.hpp"

namespace magvine::design::detail {

/// The unit vector (sin θ cos φ, sin θ sin φ, cos θ) and its derivatives in θ and φ.
Vec3 spherical(double theta, double phi);
Vec3 spherical_d_theta(double theta, double phi);
Vec3 spherical_d_phi(double theta, double phi);
/// (θ, φ) of a direction (θ = π/2, φ = 0 for zero).
std::pair<double, double> angles_of(const Vec3& d);

/// Levenberg–Marquardt (least_squares.cpp, calibration.cpp) in unbounded u for a parameter bounded to [lo, hi]:
/// x = lo + (hi − lo)(1 + sin u)/2, dx/du = (hi − lo) cos(u)/2; the inverse starts within 90 % of the range (on a
/// bound dx/du = 0 and the fit could never move it).
inline double from_unbounded(double u, double lo, double hi) {
  return lo + (hi - lo) * 0.5 * (1.0 + std::sin(u));
}
inline double from_unbounded_slope(double u, double lo, double hi) {
  return (hi - lo) * 0.5 * std::cos(u);
}
inline double to_unbounded(double x, double lo, double hi) {
  const double span = hi - lo;
  return span > 0.0 ? std::asin(std::clamp(2.0 * (x - lo) / span - 1.0, -0.9, 0.9)) : 0.0;
}
/// Whether MINPACK's status (Eigen's LevenbergMarquardt) is one of its convergence tests.
inline bool minpack_converged(Eigen::LevenbergMarquardtSpace::Status status) {
  using Eigen::LevenbergMarquardtSpace::Status;
  return status == Status::RelativeReductionTooSmall || status == Status::RelativeErrorTooSmall ||
         status == Status::RelativeErrorAndReductionTooSmall || status == Status::CosinusTooSmall;
}

/// Keeps the best design evaluated so far, the history of evaluations and the progress calls.
class BestTracker {
 public:
  /// `counts_iterations`: the optimiser calls iterate(); otherwise every evaluation is an iteration.
  BestTracker(DesignObjective& objective, const Stopwatch& clock, std::function<void(int, double)> progress,
              bool counts_iterations = false);
  /// After objective.evaluate(p) returned j.
  void record(const VecX& p, double j);
  /// An iteration began (a gradient or Jacobian was taken).
  void iterate() { ++m_iterations; }
  int iterations() const { return m_iterations; }
  double best_rms() const { return m_best_rms; }
  /// Fills the result's design, state, RMS, maximum error, evaluations, history and runtime from the best.
  void finish(DesignResult& out) const;

 private:
  DesignObjective& m_objective;
  const Stopwatch& m_clock;
  std::function<void(int, double)> m_progress;
  double m_best_rms = std::numeric_limits<double>::infinity();
  VecX m_best_p;
  std::vector<robot::RodState> m_best_states;
  std::vector<DesignResult::Step> m_history;
  int m_iterations = 0;
  bool m_counts_iterations = false;
};

}  // namespace magvine::design::detail
