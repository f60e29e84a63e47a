// The design as the least-squares problem it is (design.hpp: least_squares_design): Levenberg–Marquardt with the
// exact Jacobian of the residuals.

#include <cmath>
#include <limits>
#include <unsupported/Eigen/LevenbergMarquardt>

#include "design_internal.hpp"

namespace magvine::design {
namespace {

/// The residuals of DesignObjective in unbounded parameters u: angles as they are, a magnitude bounded to [lo, hi]
/// as lo + (hi − lo)(1 + sin u)/2.
struct Residuals : Eigen::DenseFunctor<double> {
  Residuals(DesignObjective& o, detail::BestTracker& tracker, int count)
      : Eigen::DenseFunctor<double>(o.parameters(), count), objective(o), best(tracker), lo(o.lower()), hi(o.upper()) {}

  VecX to_p(const VecX& u) const {
    VecX p = u;
    for (Eigen::Index i = 0; i < u.size(); ++i) {
      if (objective.is_bounded(static_cast<int>(i))) p[i] = detail::from_unbounded(u[i], lo[i], hi[i]);
    }
    return p;
  }
  VecX to_u(const VecX& p) const {
    VecX u = p;
    for (Eigen::Index i = 0; i < p.size(); ++i) {
      if (objective.is_bounded(static_cast<int>(i))) u[i] = detail::to_unbounded(p[i], lo[i], hi[i]);
    }
    return u;
  }

  /// A failed equilibrium reads as residuals of 1 m each: far worse than any design, so the step is refused.
  int operator()(const VecX& u, VecX& r) {
    const VecX p = to_p(u);
    VecX own;
    const bool ok = objective.residuals(p, own, nullptr);
    r = VecX::Zero(values());
    if (ok) {
      r.head(own.size()) = own;
    } else {
      r.setConstant(1.0);
    }
    best.record(p, ok ? own.squaredNorm() : std::numeric_limits<double>::infinity());
    return 0;
  }

  int df(const VecX& u, MatX& jacobian) {
    if (best.iterations() >= max_iterations) return -1;  // LM stops (UserAsked)
    best.iterate();
    const VecX p = to_p(u);
    VecX own;
    MatX j;
    jacobian = MatX::Zero(values(), inputs());
    if (!objective.residuals(p, own, &j)) {  // (LM asks at accepted points, whose equilibria were stable)
      jacobian_failed = true;
      return -1;
    }
    for (Eigen::Index i = 0; i < u.size(); ++i) {
      if (objective.is_bounded(static_cast<int>(i))) j.col(i) *= detail::from_unbounded_slope(u[i], lo[i], hi[i]);
    }
    jacobian.topRows(j.rows()) = j;
    return 0;
  }

  DesignObjective& objective;
  detail::BestTracker& best;
  int max_iterations = 100;
  bool jacobian_failed = false;
  VecX lo;
  VecX hi;
};

}  // namespace

DesignResult least_squares_design(const DesignProblem& problem, const Design& start, const DesignOptions& options) {
  const Stopwatch clock;
  DesignObjective objective(problem);
  detail::BestTracker best(objective, clock, options.progress, true);
  // MINPACK needs at least as many residuals as unknowns: zeros pad a short target.
  const int values = std::max(objective.residual_count(), objective.parameters());
  Residuals f(objective, best, values);
  f.max_iterations = options.max_iterations;
  VecX u = f.to_u(objective.parameters_of(start));
  Eigen::LevenbergMarquardt<Residuals> lm(f);
  // Tolerances: relative changes of 1e-10 in J and in the parameters, and a Jacobian-residual cosine of 1e-12, all
  // below what the equilibria (solved to a scaled gradient of 1e-9) resolve; each iteration one Jacobian.
  lm.setFtol(1e-10);
  lm.setXtol(1e-10);
  lm.setGtol(1e-12);
  lm.setMaxfev(10 * options.max_iterations);  // (the iterations are capped in Residuals::df)
  const Eigen::LevenbergMarquardtSpace::Status status = lm.minimize(u);
  DesignResult out;
  out.iterations = best.iterations();
  using Eigen::LevenbergMarquardtSpace::Status;
  if (detail::minpack_converged(status)) {
    out.converged = true;
    out.message = "converged (J's relative reduction, the step or the gradient below tolerance)";
  } else if (status == Status::UserAsked) {
    out.message = f.jacobian_failed ? "stopped: no sensitivity at an accepted design (its equilibrium failed)"
                                    : "stopped at the iteration limit";
  } else if (status == Status::TooManyFunctionEvaluation) {
    out.message = "stopped at the evaluation limit (10 per allowed iteration)";
  } else {
    out.message = "stopped: no further progress at the equilibria's precision (MINPACK status " +
                  std::to_string(static_cast<int>(status)) + ")";
  }
  best.finish(out);
  return out;
}

}  // namespace magvine::design
