// The derivative-free baseline of the design (design.hpp: bayesian_design): Bayesian optimisation as the thesis used
// it (appendix A.1.4, after Snoek et al. 2012): a Gaussian-process surrogate of the objective and the expected
// improvement as the acquisition. Written here on Eigen; it exists to measure what the exact gradient gains.

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "design_internal.hpp"
#include "magvine/core/units.hpp"

namespace magvine::design {
namespace {

/// The surrogate: a zero-mean GP on standardised y with the kernel exp(−|a − b|²/(2ℓ²)) on the unit cube and a small
/// noise (the equilibrium is deterministic; the nugget keeps the factor well conditioned).
struct Surrogate {
  std::vector<VecX> x;
  VecX y;  ///< standardised
  double length = 0.3;
  Eigen::LLT<MatX> factor;
  VecX alpha;  ///< K⁻¹ y

  static constexpr double kNugget = 1e-6;

  double kernel(const VecX& a, const VecX& b) const {
    return std::exp(-(a - b).squaredNorm() / (2.0 * length * length));
  }

  /// Factors K at the current length; the log marginal likelihood (−∞ when K is not positive definite).
  double fit() {
    const auto n = static_cast<Eigen::Index>(x.size());
    MatX k(n, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = 0; j <= i; ++j)
        k(i, j) = k(j, i) = kernel(x[static_cast<std::size_t>(i)], x[static_cast<std::size_t>(j)]);
      k(i, i) += kNugget;
    }
    factor.compute(k);
    if (factor.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
    alpha = factor.solve(y);
    const MatX l = factor.matrixL();
    return -0.5 * y.dot(alpha) - l.diagonal().array().log().sum();
  }

  /// Mean and standard deviation of the standardised objective at z.
  std::pair<double, double> predict(const VecX& z) const {
    const auto n = static_cast<Eigen::Index>(x.size());
    VecX k(n);
    for (Eigen::Index i = 0; i < n; ++i) k[i] = kernel(z, x[static_cast<std::size_t>(i)]);
    const VecX v = factor.matrixL().solve(k);
    return {k.dot(alpha), std::sqrt(std::max(1e-12, 1.0 + kNugget - v.squaredNorm()))};
  }
};

/// Expected improvement below `best` of a normal prediction (mean, sd) (Jones et al. 1998).
double expected_improvement(double mean, double sd, double best) {
  const double gain = best - mean;
  const double z = gain / sd;
  const double cdf = 0.5 * std::erfc(-z / std::sqrt(2.0));
  const double pdf = std::exp(-0.5 * z * z) / std::sqrt(2.0 * kPi);
  return gain * cdf + sd * pdf;
}

}  // namespace

DesignResult bayesian_design(const DesignProblem& problem, const DesignOptions& options, int initial) {
  const Stopwatch clock;
  DesignObjective objective(problem);
  detail::BestTracker best(objective, clock, options.progress);
  // The box: φ over one turn (the gradient optimiser's ±2π lets it cross ±π; the search here needs no double cover).
  VecX lo = objective.lower();
  VecX hi = objective.upper();
  for (Eigen::Index i = 0; i < lo.size(); ++i) {
    if (lo[i] < -kPi) lo[i] = -kPi;
    if (hi[i] > kPi && lo[i] < 0.0) hi[i] = kPi;
  }
  const auto dims = static_cast<Eigen::Index>(objective.parameters());
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<VecX> zs;
  std::vector<double> ys;  // log J [mm²]
  const auto evaluate = [&](const VecX& z) {
    const VecX p = lo + z.cwiseProduct(hi - lo);
    const double j = objective.evaluate(p, nullptr);
    best.record(p, j);
    zs.push_back(z);
    ys.push_back(std::isfinite(j) ? std::log(1e6 * j + 1e-12) : std::numeric_limits<double>::quiet_NaN());
  };
  const auto random_point = [&] {
    VecX z(dims);
    for (Eigen::Index i = 0; i < dims; ++i) z[i] = unit(rng);
    return z;
  };
  // The first design is the gradient optimiser's random start for the same seed (the same start for both).
  {
    DesignObjective layout(problem);
    const VecX p = layout.parameters_of(random_design(problem, options.seed));
    evaluate(((p - lo).cwiseQuotient(hi - lo)).cwiseMax(0.0).cwiseMin(1.0));
  }
  for (int i = 1; i < initial; ++i) evaluate(random_point());
  Surrogate gp;
  for (int it = 0; it < options.max_iterations; ++it) {
    // Standardise y; a failed equilibrium counts as the worst value seen (it lies where designs are bad).
    double worst = -std::numeric_limits<double>::infinity();
    for (const double y : ys) {
      if (!std::isnan(y)) worst = std::max(worst, y);
    }
    if (!std::isfinite(worst)) worst = 0.0;
    gp.x = zs;
    gp.y.resize(static_cast<Eigen::Index>(ys.size()));
    for (std::size_t i = 0; i < ys.size(); ++i)
      gp.y[static_cast<Eigen::Index>(i)] = std::isnan(ys[i]) ? worst + 1.0 : ys[i];
    const double mean = gp.y.mean();
    const double sd = std::max(1e-9, std::sqrt((gp.y.array() - mean).square().mean()));
    gp.y = (gp.y.array() - mean) / sd;
    // The length scale by marginal likelihood over a grid (in units of the cube's diagonal).
    double best_length = 0.3;
    double best_likelihood = -std::numeric_limits<double>::infinity();
    for (const double fraction : {0.05, 0.1, 0.2, 0.35, 0.6, 1.0}) {
      gp.length = fraction * std::sqrt(static_cast<double>(dims));
      const double l = gp.fit();
      if (l > best_likelihood) {
        best_likelihood = l;
        best_length = gp.length;
      }
    }
    gp.length = best_length;
    gp.fit();
    const double y_best = gp.y.minCoeff();
    // Candidates: uniform over the cube and around the best points so far, at two scales.
    std::vector<std::size_t> order(zs.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return gp.y[static_cast<Eigen::Index>(a)] < gp.y[static_cast<Eigen::Index>(b)];
    });
    VecX chosen = random_point();
    double chosen_ei = -1.0;
    const auto offer = [&](const VecX& z) {
      const auto [m, s] = gp.predict(z);
      const double ei = expected_improvement(m, s, y_best);
      if (ei > chosen_ei) {
        chosen_ei = ei;
        chosen = z;
      }
    };
    for (int c = 0; c < 1000; ++c) offer(random_point());
    for (std::size_t r = 0; r < std::min<std::size_t>(5, order.size()); ++r) {
      for (const double scale : {0.02, 0.1}) {
        for (int c = 0; c < 100; ++c) {
          VecX z = zs[order[r]];
          for (Eigen::Index i = 0; i < dims; ++i) z[i] = std::clamp(z[i] + scale * normal(rng), 0.0, 1.0);
          offer(z);
        }
      }
    }
    evaluate(chosen);
  }
  DesignResult out;
  out.iterations = objective.evaluations();
  out.converged = false;
  out.message = "the evaluation budget spent (Bayesian optimisation has no convergence test)";
  best.finish(out);
  return out;
}

}  // namespace magvine::design
