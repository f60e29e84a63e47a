// Calibration (calibration.hpp): continuation of each case's approach, the measured quantities and their exact
// sensitivities, and the Levenberg–Marquardt fit with its Gauss–Newton covariance.

#include "magvine/design/calibration.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <unsupported/Eigen/LevenbergMarquardt>

#include "design_internal.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/magnetics/field_function.hpp"

namespace magvine::design {
namespace {

/// A quantity of an equilibrium and its covector on the rod's unknowns (rod_gradient's layout).
struct Quantity {
  double value = 0.0;
  VecX covector;
};

/// The tip node's three position unknowns start here (block N − 1: node N's position, then edge N − 1's rotation).
Eigen::Index tip_offset(const robot::RodState& s) {
  return 6 * static_cast<Eigen::Index>(s.frames.size() - 1);
}

/// The chord angle a = acos(ĉ·t0) between the base tangent t0 and the chord c = tip − base;
/// da/dtip = −(t0 − (ĉ·t0)ĉ)/(|c| sin a).
Quantity chord_angle(const robot::RodModel& m, const robot::RodState& s) {
  const Vec3 t0 = m.base_frame.col(0);
  const Vec3 chord = s.tip() - m.base_position;
  const Vec3 c = chord.normalized();
  const double cosine = std::clamp(c.dot(t0), -1.0, 1.0);
  Quantity q{std::acos(cosine), VecX::Zero(6 * static_cast<Eigen::Index>(s.frames.size()))};
  const double sine = std::sin(q.value);
  if (sine > 1e-12) q.covector.segment<3>(tip_offset(s)) = -(t0 - cosine * c) / (chord.norm() * sine);
  return q;
}

/// The bend angle a = acos(t·t0) of the tip tangent t; a rotation δφ of the last edge turns t by δφ × t, so
/// da/dδφ = −(t × t0)/sin a.
Quantity bend_angle(const robot::RodModel& m, const robot::RodState& s) {
  const Vec3 t0 = m.base_frame.col(0);
  const Vec3 t = s.tip_tangent();
  const double cosine = std::clamp(t.dot(t0), -1.0, 1.0);
  Quantity q{std::acos(cosine), VecX::Zero(6 * static_cast<Eigen::Index>(s.frames.size()))};
  const double sine = std::sin(q.value);
  if (sine > 1e-12) q.covector.segment<3>(tip_offset(s) + 3) = -t.cross(t0) / sine;
  return q;
}

Quantity observe(Observable o, const robot::RodModel& m, const robot::RodState& s) {
  switch (o) {
    case Observable::chord_angle:
    case Observable::critical_distance:
      return chord_angle(m, s);
    case Observable::bend_angle:
      return bend_angle(m, s);
    case Observable::tip_x:
    case Observable::tip_y:
    case Observable::tip_z: {
      const int axis = o == Observable::tip_x ? 0 : (o == Observable::tip_y ? 1 : 2);
      Quantity q{s.tip()[axis], VecX::Zero(6 * static_cast<Eigen::Index>(s.frames.size()))};
      q.covector[tip_offset(s) + axis] = 1.0;
      return q;
    }
  }
  return {};
}

/// One case's approach at θ: the field of the magnet at distance d and the continuation of the equilibrium.
class Approach {
 public:
  Approach(const CalibrationCase& c, const VecX& theta) : m_case(c), m_theta(theta), m_model(build(c, theta)) {}

  /// The case's model at θ; parameters the model refuses (a film so soft that the pressure bursts it) are a failed
  /// prediction, as a failed equilibrium is: the fit steps back.
  static robot::RodModel build(const CalibrationCase& c, const VecX& theta) {
    try {
      return c.model(theta);
    } catch (const InputError& e) {
      throw NumericalError(c.label + ": the model refuses these parameters: " + e.what());
    }
  }

  robot::RodField field_at(double d) const { return magnetics::field_function(m_case.magnet, {pose_at(d)}); }
  magnetics::Pose pose_at(double d) const {
    magnetics::Pose pose = m_case.magnet.rest_poses.front();
    pose.position += (d - m_case.start_distance) * m_case.approach;
    return pose;
  }
  const robot::RodModel& model() const { return m_model; }

  /// The equilibrium at d: from the straight body with the load ramp (the first), or by Newton from `from` (the
  /// body follows the magnet). Empty when it fails.
  std::optional<robot::RodState> solve(double d, const robot::RodState* from, int& equilibria) const {
    robot::RodState s = from != nullptr ? *from : robot::straight_rod(m_model);
    robot::RodSolveOptions options = m_case.solver;
    if (from != nullptr) options.ramp = false;
    ++equilibria;
    const robot::RodSolveReport report = robot::solve_rod_statics(m_model, field_at(d), s, options);
    if (!report.converged) return std::nullopt;
    return s;
  }

  /// ∂g/∂θ (6N × P, central differences of the analytic gradient at the fixed configuration) and, with `by_distance`,
  /// ∂g/∂d in one more column (the magnet's translation along u).
  MatX gradient_sensitivity(const robot::RodState& s, double d, const std::vector<CalibrationParameter>& params,
                            bool by_distance) const {
    const robot::RodField field = field_at(d);
    const Eigen::Index p = m_theta.size();
    MatX out(6 * static_cast<Eigen::Index>(s.frames.size()), p + (by_distance ? 1 : 0));
    for (Eigen::Index i = 0; i < p; ++i) {
      const CalibrationParameter& param = params[static_cast<std::size_t>(i)];
      // A step of 1e-6 of the range: the difference's truncation error (h²) far below the equilibria's precision and
      // its round-off (ε|g|/h) too.
      const double h = 1e-6 * (param.upper - param.lower);
      VecX plus = m_theta;
      VecX minus = m_theta;
      plus[i] += h;
      minus[i] -= h;
      out.col(i) =
          (robot::rod_gradient(build(m_case, plus), field, s) - robot::rod_gradient(build(m_case, minus), field, s)) /
          (2.0 * h);
    }
    if (by_distance) out.col(p) = robot::rod_field_translation_sensitivity(m_model, field, s) * m_case.approach;
    return out;
  }

 private:
  const CalibrationCase& m_case;
  const VecX& m_theta;
  robot::RodModel m_model;
};

/// dx*/dθ (and dx*/dd) = −H⁻¹ ∂g/∂(θ, d) at an equilibrium; NumericalError when it is not stable.
MatX state_sensitivity(const Approach& a, const robot::RodState& s, double d,
                       const std::vector<CalibrationParameter>& params, bool by_distance, const std::string& where) {
  const MatX dg = a.gradient_sensitivity(s, d, params, by_distance);
  const std::optional<MatX> solved = robot::rod_hessian_solve(a.model(), a.field_at(d), s, dg);
  if (!solved) throw NumericalError(where + ": the equilibrium is not stable (no sensitivity)");
  return -*solved;
}

std::string distance_label(const CalibrationCase& c, double d) {
  return c.label + " at d = " + std::to_string(d * 1e3) + " mm";
}

/// Runs one case's approach, filling the predictions of its measurements.
void predict_case(const CalibrationProblem& problem, std::size_t index, const VecX& theta, bool jacobian,
                  Predictions& out) {
  const CalibrationCase& c = problem.cases[index];
  const Approach approach(c, theta);
  const Eigen::Index p = theta.size();
  // The distances asked for, farthest first (the magnet approaches), and the critical-distance measurements.
  std::vector<std::size_t> at_distance;
  std::vector<std::size_t> critical;
  for (std::size_t i = 0; i < problem.measurements.size(); ++i) {
    const Measurement& m = problem.measurements[i];
    if (m.case_index != index) continue;
    (m.observable == Observable::critical_distance ? critical : at_distance).push_back(i);
  }
  std::ranges::sort(at_distance, [&](std::size_t a, std::size_t b) {
    return problem.measurements[a].distance > problem.measurements[b].distance;
  });
  // dx*/dθ of the equilibrium the measurements at one distance share: solved once for all of them.
  std::optional<double> sensitivity_at;
  MatX dx;
  const auto record = [&](std::size_t i, const robot::RodState& s, double d) {
    const Quantity q = observe(problem.measurements[i].observable, approach.model(), s);
    out.values[static_cast<Eigen::Index>(i)] = q.value;
    if (!jacobian) return;
    if (sensitivity_at != d) {
      dx = state_sensitivity(approach, s, d, problem.parameters, false, distance_label(c, d));
      sensitivity_at = d;
    }
    out.jacobian.row(static_cast<Eigen::Index>(i)) = q.covector.transpose() * dx;
  };
  const auto record_critical = [&](const robot::RodState& s, double d) {
    for (const std::size_t i : critical) out.values[static_cast<Eigen::Index>(i)] = d;
    if (!jacobian) return;
    // a(x*(d, θ)) = a_c: dd*/dθ = −(∂a/∂θ)/(∂a/∂d), one row for every critical-distance measurement of the case.
    const Quantity q = chord_angle(approach.model(), s);
    const MatX dg = approach.gradient_sensitivity(s, d, problem.parameters, true);
    const std::optional<MatX> solved = robot::rod_hessian_solve(approach.model(), approach.field_at(d), s, dg);
    VecX da;
    if (solved) {
      da = -solved->transpose() * q.covector;  // (∂a/∂θ, ∂a/∂d)
    } else {
      // At the fold itself (a snap: the search ends within 1e-12 m of it and H may have lost its last pivot), the
      // limit of the ratio: H⁻¹ ≈ φφᵀ/λ, so dd*/dθ = −φᵀ∂g/∂θ / φᵀ∂g/∂d (φ the eigenvector of H's smallest
      // eigenvalue).
      const Eigen::SelfAdjointEigenSolver<MatX> eigen(robot::rod_hessian(approach.model(), approach.field_at(d), s));
      da = dg.transpose() * eigen.eigenvectors().col(0);
    }
    if (!(std::abs(da[p]) > 0.0)) throw NumericalError(c.label + ": the chord angle does not change with the distance");
    for (const std::size_t i : critical)
      out.jacobian.row(static_cast<Eigen::Index>(i)) = -da.head(p).transpose() / da[p];
  };

  double d = c.start_distance;
  std::optional<robot::RodState> state = approach.solve(d, nullptr, out.equilibria);
  if (!state) throw NumericalError(distance_label(c, d) + ": the first equilibrium failed");
  std::size_t next = 0;
  bool critical_pending = !critical.empty();
  const double tolerance = 1e-12;
  while (next < at_distance.size() && problem.measurements[at_distance[next]].distance >= d - tolerance) {
    record(at_distance[next++], *state, d);
  }
  if (critical_pending && chord_angle(approach.model(), *state).value >= c.critical_angle) {
    record_critical(*state, d);  // already past the threshold at the start
    critical_pending = false;
  }
  bool unreached = false;
  while (next < at_distance.size() || critical_pending) {
    if (critical_pending && d <= c.closest + tolerance) {  // the critical search ends at `closest`
      critical_pending = false;
      unreached = true;
      continue;
    }
    const double target = next < at_distance.size() ? problem.measurements[at_distance[next]].distance : c.closest;
    const double goal = critical_pending ? std::max(target, c.closest) : target;
    // A step Newton cannot follow (the body moves far, as at a snap) is taken in halves, down to 1/64 of it.
    double d_next = std::max(d - c.step, goal);
    std::optional<robot::RodState> after = approach.solve(d_next, &*state, out.equilibria);
    for (int halving = 0; !after && halving < 6; ++halving) {
      d_next = 0.5 * (d + d_next);
      after = approach.solve(d_next, &*state, out.equilibria);
    }
    if (!after) throw NumericalError(distance_label(c, d_next) + ": the equilibrium failed on the approach");
    if (critical_pending && chord_angle(approach.model(), *after).value >= c.critical_angle) {
      // Bisection between d (below a_c) and d_next (at or above it), following the branch from d, to 1e-12 m: the
      // equilibria resolve the angle to ~1e-12 rad, so d* is as precise as they are (and its finite differences
      // in the tests are not limited by the search).
      double below = d;
      double above = d_next;
      robot::RodState below_state = *state;
      while (below - above > 1e-12) {
        const double mid = 0.5 * (below + above);
        const std::optional<robot::RodState> s = approach.solve(mid, &below_state, out.equilibria);
        if (s && chord_angle(approach.model(), *s).value < c.critical_angle) {
          below = mid;
          below_state = *s;
        } else {
          above = mid;
        }
      }
      record_critical(below_state, below);
      critical_pending = false;
    }
    d = d_next;
    state = std::move(after);
    while (next < at_distance.size() && problem.measurements[at_distance[next]].distance >= d - tolerance) {
      record(at_distance[next++], *state, d);
    }
  }
  for (const std::size_t i : critical) {
    if (!unreached) continue;
    out.values[static_cast<Eigen::Index>(i)] = c.closest;  // never reached: a zero row
    out.reached[i] = false;
  }
}

/// The weighted residuals of the fitted measurements in unbounded parameters u (θ = lo + (hi − lo)(1 + sin u)/2).
struct Residuals : Eigen::DenseFunctor<double> {
  Residuals(const CalibrationProblem& p, std::vector<std::size_t> fit, int values)
      : Eigen::DenseFunctor<double>(static_cast<int>(p.parameters.size()), values),
        problem(p),
        fitted(std::move(fit)) {}

  VecX to_theta(const VecX& u) const {
    VecX theta(u.size());
    for (Eigen::Index i = 0; i < u.size(); ++i) {
      const CalibrationParameter& q = problem.parameters[static_cast<std::size_t>(i)];
      theta[i] = detail::from_unbounded(u[i], q.lower, q.upper);
    }
    return theta;
  }
  VecX to_u(const VecX& theta) const {
    VecX u(theta.size());
    for (Eigen::Index i = 0; i < theta.size(); ++i) {
      const CalibrationParameter& q = problem.parameters[static_cast<std::size_t>(i)];
      u[i] = detail::to_unbounded(theta[i], q.lower, q.upper);
    }
    return u;
  }
  VecX weighted(const Predictions& y) const {
    VecX r = VecX::Zero(values());
    for (std::size_t k = 0; k < fitted.size(); ++k) {
      const Measurement& m = problem.measurements[fitted[k]];
      r[static_cast<Eigen::Index>(k)] = (y.values[static_cast<Eigen::Index>(fitted[k])] - m.value) / m.sigma;
    }
    return r;
  }

  /// A failed approach reads as residuals of 1e6 σ: the step is refused.
  int operator()(const VecX& u, VecX& r) {
    ++evaluations;
    try {
      const Predictions y = predict(problem, to_theta(u), false);
      equilibria += y.equilibria;
      r = weighted(y);
    } catch (const NumericalError&) {
      r = VecX::Constant(values(), 1e6);
    }
    return 0;
  }

  int df(const VecX& u, MatX& jacobian) {
    if (iterations >= max_iterations) return -1;  // LM stops (UserAsked)
    ++iterations;
    ++evaluations;
    jacobian = MatX::Zero(values(), inputs());
    try {
      const Predictions y = predict(problem, to_theta(u), true);
      equilibria += y.equilibria;
      for (std::size_t k = 0; k < fitted.size(); ++k) {
        const Measurement& m = problem.measurements[fitted[k]];
        jacobian.row(static_cast<Eigen::Index>(k)) = y.jacobian.row(static_cast<Eigen::Index>(fitted[k])) / m.sigma;
      }
      for (Eigen::Index i = 0; i < u.size(); ++i) {
        const CalibrationParameter& q = problem.parameters[static_cast<std::size_t>(i)];
        jacobian.col(i) *= detail::from_unbounded_slope(u[i], q.lower, q.upper);
      }
      const double chi = weighted(y).norm();
      history.push_back(chi);
      if (progress) progress(iterations, chi);
    } catch (const NumericalError&) {
      failed = true;
      return -1;
    }
    return 0;
  }

  const CalibrationProblem& problem;
  std::vector<std::size_t> fitted;
  int max_iterations = 50;
  int iterations = 0;
  int evaluations = 0;
  int equilibria = 0;
  bool failed = false;
  std::vector<double> history;
  std::function<void(int, double)> progress;
};

}  // namespace

const char* observable_name(Observable o) {
  switch (o) {
    case Observable::chord_angle:
      return "chord_angle";
    case Observable::bend_angle:
      return "bend_angle";
    case Observable::tip_x:
      return "tip_x";
    case Observable::tip_y:
      return "tip_y";
    case Observable::tip_z:
      return "tip_z";
    case Observable::critical_distance:
      return "critical_distance";
  }
  return "?";
}

void check_calibration_problem(const CalibrationProblem& problem, const std::string& where) {
  const auto fail = [&](const std::string& key, const std::string& what) { throw InputError(where, 0, key, what); };
  if (problem.parameters.empty()) fail("calibrate.parameters", "no parameter to fit");
  for (const CalibrationParameter& q : problem.parameters) {
    const std::string key = "calibrate.parameters." + q.name;
    if (!std::isfinite(q.lower) || !std::isfinite(q.upper) || !(q.lower < q.upper)) {
      fail(key, "needs finite bounds with min < max");
    }
    if (!(q.start >= q.lower && q.start <= q.upper)) fail(key, "its start lies outside [min, max]");
  }
  int fitted = 0;
  for (std::size_t i = 0; i < problem.measurements.size(); ++i) {
    const Measurement& m = problem.measurements[i];
    const std::string key = "measurement " + std::to_string(i + 1);
    if (m.case_index >= problem.cases.size()) fail(key, "names no case");
    if (!std::isfinite(m.value)) fail(key, "value is not a finite number");
    if (!(m.sigma > 0.0) || !std::isfinite(m.sigma)) fail(key, "sigma must be positive");
    const CalibrationCase& c = problem.cases[m.case_index];
    if (m.observable != Observable::critical_distance &&
        !(m.distance <= c.start_distance + 1e-12 && m.distance > 0.0)) {
      fail(key, "its distance must be positive and no farther than where the magnet starts (" +
                    std::to_string(c.start_distance * 1e3) + " mm)");
    }
    if (!m.holdout) ++fitted;
  }
  if (fitted == 0) fail("measurements", "every measurement is held out: nothing to fit");
  for (const CalibrationCase& c : problem.cases) {
    if (c.magnet.size() != 1) fail(c.label, "needs exactly one magnet (the one that approaches)");
    if (!(c.step > 0.0) || !(c.closest > 0.0) || !(c.closest < c.start_distance)) {
      fail(c.label, "needs a positive step and 0 < closest < the magnet's start distance");
    }
  }
}

Predictions predict(const CalibrationProblem& problem, const VecX& theta, bool jacobian) {
  Predictions out;
  const Eigen::Index count = static_cast<Eigen::Index>(problem.measurements.size());
  out.values = VecX::Zero(count);
  out.jacobian = MatX::Zero(jacobian ? count : 0, theta.size());
  out.reached.assign(problem.measurements.size(), true);
  for (std::size_t c = 0; c < problem.cases.size(); ++c) predict_case(problem, c, theta, jacobian, out);
  return out;
}

CalibrationResult calibrate(const CalibrationProblem& problem, const CalibrationOptions& options) {
  const Stopwatch clock;
  std::vector<std::size_t> fitted;
  for (std::size_t i = 0; i < problem.measurements.size(); ++i) {
    if (!problem.measurements[i].holdout) fitted.push_back(i);
  }
  const Eigen::Index p = static_cast<Eigen::Index>(problem.parameters.size());
  // MINPACK needs at least as many residuals as unknowns: zeros pad an under-determined fit (its covariance then says
  // which directions the data do not see).
  const int values = std::max(static_cast<int>(fitted.size()), static_cast<int>(p));
  Residuals f(problem, fitted, values);
  f.max_iterations = options.max_iterations;
  f.progress = options.progress;
  VecX start(p);
  for (Eigen::Index i = 0; i < p; ++i) start[i] = problem.parameters[static_cast<std::size_t>(i)].start;
  VecX u = f.to_u(start);
  Eigen::LevenbergMarquardt<Residuals> lm(f);
  // Relative changes of 1e-10 in χ² and in u, a gradient cosine of 1e-12: below what the equilibria resolve.
  lm.setFtol(1e-10);
  lm.setXtol(1e-10);
  lm.setGtol(1e-12);
  lm.setMaxfev(10 * options.max_iterations);
  using Eigen::LevenbergMarquardtSpace::Status;
  const Status status = lm.minimize(u);

  CalibrationResult out;
  out.theta = f.to_theta(u);
  out.iterations = f.iterations;
  out.history = f.history;
  if (detail::minpack_converged(status)) {
    out.converged = true;
    out.message = "converged (χ²'s relative reduction, the step or the gradient below tolerance)";
  } else if (status == Status::UserAsked) {
    out.message = f.failed ? "stopped: an equilibrium of the approach failed at an accepted fit"
                           : "stopped at the iteration limit";
  } else {
    out.message = "stopped: no further progress (MINPACK status " + std::to_string(static_cast<int>(status)) + ")";
  }
  out.predictions = predict(problem, out.theta, true);
  out.evaluations = f.evaluations + 1;
  out.equilibria = f.equilibria + out.predictions.equilibria;
  out.fitted = static_cast<int>(fitted.size());

  // C = (JᵀWJ)⁻¹ on the range-scaled parameters (θ_i/(hi − lo): moduli and fractions alike of order one), by SVD:
  // a direction the fitted measurements do not see has an infinite variance.
  const Eigen::Index m = static_cast<Eigen::Index>(fitted.size());
  MatX jw(m, p);
  VecX scale(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    const CalibrationParameter& q = problem.parameters[static_cast<std::size_t>(i)];
    scale[i] = q.upper - q.lower;
  }
  out.chi2 = 0.0;
  for (Eigen::Index k = 0; k < m; ++k) {
    const Measurement& mm = problem.measurements[fitted[static_cast<std::size_t>(k)]];
    const Eigen::Index row = static_cast<Eigen::Index>(fitted[static_cast<std::size_t>(k)]);
    jw.row(k) = out.predictions.jacobian.row(row).cwiseProduct(scale.transpose()) / mm.sigma;
    out.chi2 += std::pow((out.predictions.values[row] - mm.value) / mm.sigma, 2);
  }
  const Eigen::JacobiSVD<MatX> svd(jw, Eigen::ComputeFullV);
  const VecX& s = svd.singularValues();
  const MatX& v = svd.matrixV();
  MatX scaled_c = MatX::Zero(p, p);
  bool blind = s.size() < p;
  for (Eigen::Index k = 0; k < s.size(); ++k) {
    if (s[k] <= 1e-10 * s[0] || s[k] == 0.0) {
      blind = true;
      continue;
    }
    scaled_c += v.col(k) * v.col(k).transpose() / (s[k] * s[k]);
  }
  out.covariance = scale.asDiagonal() * scaled_c * scale.asDiagonal();
  out.sigma = out.covariance.diagonal().cwiseSqrt();
  if (blind) {
    // The unseen directions: every parameter with a share in them has no bound on its uncertainty.
    for (Eigen::Index k = 0; k < p; ++k) {
      const bool unseen = k >= s.size() || s[k] <= 1e-10 * s[0] || s[k] == 0.0;
      if (!unseen) continue;
      for (Eigen::Index i = 0; i < p; ++i) {
        if (std::abs(v(i, k)) > 1e-8) out.sigma[i] = std::numeric_limits<double>::infinity();
      }
    }
    out.message += "; some parameter combination is not determined by the fitted measurements";
  }
  out.prediction_sigma = VecX::Zero(static_cast<Eigen::Index>(problem.measurements.size()));
  for (Eigen::Index i = 0; i < out.prediction_sigma.size(); ++i) {
    const VecX j = out.predictions.jacobian.row(i).transpose();
    out.prediction_sigma[i] = std::sqrt(std::max(0.0, j.dot(out.covariance * j)));
  }
  out.runtime_s = clock.seconds();
  return out;
}

}  // namespace magvine::design
