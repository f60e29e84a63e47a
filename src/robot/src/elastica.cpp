#include "magvine/robot/elastica.hpp"

#include <cmath>
#include <string>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::robot {
namespace {

/// ODE state (x, y, θ, n_x, n_y, m).
using State = Eigen::Matrix<double, 6, 1>;

class Shooter {
 public:
  Shooter(const ElasticaProblem& p, int intervals) : m_p(p), m_n(intervals), m_h(p.length / intervals) {}

  /// dState/ds with the distributed loads scaled by λ.
  State rhs(const State& y, double lambda) const {
    const double c = std::cos(y[2]);
    const double s = std::sin(y[2]);
    Eigen::Vector2d f = m_p.density * m_p.area * m_p.gravity;
    double tau = 0.0;
    if (m_p.field && m_p.remanence != 0.0 && m_p.area > 0.0) {
      const magnetics::FieldSample sample = m_p.field(Vec3(y[0], y[1], 0.0));
      // The moment per length A·Br/μ0 along the magnetisation d, and its wrench (torque about z, force in plane).
      const Vec3 d = m_p.magnetisation == PlanarMagnetisation::kAxial ? Vec3(c, s, 0.0) : Vec3(-s, c, 0.0);
      const magnetics::Wrench w =
          magnetics::magnetic_wrench(magnetics::hard_magnetic_moment<3>(Vec3(m_p.remanence * d), m_p.area), sample);
      tau = w.torque.z();
      f += w.force.head<2>();
    }
    State out;
    out << c, s, y[5] / m_p.bending_stiffness, -lambda * f.x(), -lambda * f.y(), -(c * y[4] - s * y[3]) - lambda * tau;
    return out;
  }

  /// Integrates from the base with reactions u = (n_x, n_y, m)(0); records the path when `out` is given.
  State shoot(const Eigen::Vector3d& u, double lambda, ElasticaSolution* out) const {
    State y;
    y << 0.0, 0.0, m_p.base_angle, u[0], u[1], u[2];
    if (out != nullptr) record(*out, 0, y);
    for (int k = 0; k < m_n; ++k) {
      const State k1 = rhs(y, lambda);
      const State k2 = rhs(y + 0.5 * m_h * k1, lambda);
      const State k3 = rhs(y + 0.5 * m_h * k2, lambda);
      const State k4 = rhs(y + m_h * k3, lambda);
      y += m_h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      if (out != nullptr) record(*out, k + 1, y);
    }
    return y;
  }

  /// Tip residual (n(L) − λF_tip, m(L) − λM_tip), scaled by EI/L² and EI/L to be dimensionless.
  Eigen::Vector3d residual(const Eigen::Vector3d& u, double lambda) const {
    const State tip = shoot(u, lambda, nullptr);
    const double force_scale = m_p.bending_stiffness / (m_p.length * m_p.length);
    const double moment_scale = m_p.bending_stiffness / m_p.length;
    return {(tip[3] - lambda * m_p.tip_force.x()) / force_scale, (tip[4] - lambda * m_p.tip_force.y()) / force_scale,
            (tip[5] - lambda * m_p.tip_moment) / moment_scale};
  }

  /// Newton on the base reactions from `u` (scaled unknowns, forward-difference Jacobian, backtracking on |r|).
  bool newton(Eigen::Vector3d& u, double lambda, double tolerance, int max_iterations, int& iterations) const {
    const Eigen::Vector3d scale(m_p.bending_stiffness / (m_p.length * m_p.length),
                                m_p.bending_stiffness / (m_p.length * m_p.length), m_p.bending_stiffness / m_p.length);
    Eigen::Vector3d r = residual(u, lambda);
    for (int it = 0; it < max_iterations; ++it) {
      if (!r.allFinite()) return false;
      if (r.norm() <= tolerance) return true;
      ++iterations;
      Eigen::Matrix3d jacobian;
      for (int j = 0; j < 3; ++j) {
        const double step = 1e-7 * std::max(1.0, std::abs(u[j] / scale[j])) * scale[j];
        Eigen::Vector3d v = u;
        v[j] += step;
        jacobian.col(j) = (residual(v, lambda) - r) / (step / scale[j]);
      }
      const Eigen::Vector3d delta = -jacobian.fullPivLu().solve(r).cwiseProduct(scale);
      if (!delta.allFinite()) return false;
      double t = 1.0;
      for (;;) {
        const Eigen::Vector3d trial = u + t * delta;
        const Eigen::Vector3d rt = residual(trial, lambda);
        if (rt.allFinite() && rt.norm() < r.norm()) {
          u = trial;
          r = rt;
          break;
        }
        t *= 0.5;
        if (t < 1e-6) return r.norm() <= 1e3 * tolerance;  // stalled at round-off: accept only near the goal
      }
    }
    return r.norm() <= tolerance;
  }

 private:
  void record(ElasticaSolution& out, int k, const State& y) const {
    const auto i = static_cast<std::size_t>(k);
    out.s[i] = k * m_h;
    out.position[i] = y.head<2>();
    out.angle[i] = y[2];
    out.moment[i] = y[5];
  }

  const ElasticaProblem& m_p;
  int m_n;
  double m_h;
};

void validate(const ElasticaProblem& p, const ElasticaOptions& o) {
  const auto bad = [](const std::string& field, double value, const std::string& allowed) {
    throw InputError("elastica: " + field + " = " + std::to_string(value) + " (must be " + allowed + ")");
  };
  if (!(p.length > 0.0) || !std::isfinite(p.length)) bad("length", p.length, "> 0");
  if (!(p.bending_stiffness > 0.0) || !std::isfinite(p.bending_stiffness)) {
    bad("bending_stiffness", p.bending_stiffness, "> 0");
  }
  if (!(p.area >= 0.0)) bad("area", p.area, ">= 0");
  if (!(p.density >= 0.0)) bad("density", p.density, ">= 0");
  if (o.intervals < 1) bad("intervals", o.intervals, ">= 1");
}

}  // namespace

ElasticaSolution solve_elastica(const ElasticaProblem& problem, const ElasticaOptions& options) {
  validate(problem, options);
  const Shooter shooter(problem, options.intervals);
  ElasticaSolution out;
  Eigen::Vector3d u = Eigen::Vector3d::Zero();  // the unloaded beam: no reactions
  double lambda = 0.0;
  double step = 1.0 / options.min_load_steps;
  const double min_step = 1.0 / options.max_load_steps;
  Eigen::Vector3d previous_u = u;
  double previous_lambda = 0.0;
  double tip_angle = problem.base_angle;
  out.converged = true;
  while (lambda < 1.0) {
    const double next = std::min(1.0, lambda + step);
    // Predictor: linear extrapolation along the ramp.
    Eigen::Vector3d guess = u;
    if (lambda > previous_lambda) guess += (u - previous_u) * ((next - lambda) / (lambda - previous_lambda));
    bool accepted = shooter.newton(guess, next, options.tolerance, options.max_newton, out.newton_iterations);
    double next_angle = tip_angle;
    if (accepted) {
      next_angle = shooter.shoot(guess, next, nullptr)[2];
      accepted = std::abs(next_angle - tip_angle) <= options.max_angle_step || step <= min_step;
    }
    if (accepted) {
      previous_u = u;
      previous_lambda = lambda;
      u = guess;
      lambda = next;
      tip_angle = next_angle;
      ++out.load_steps;
      step = std::min(2.0 * step, 1.0 / options.min_load_steps);
    } else {
      step *= 0.5;
      if (step < min_step) {
        out.converged = false;
        break;
      }
    }
  }
  const auto samples = static_cast<std::size_t>(options.intervals) + 1;
  out.s.resize(samples);
  out.position.resize(samples);
  out.angle.resize(samples);
  out.moment.resize(samples);
  shooter.shoot(u, lambda, &out);
  out.base_force = u.head<2>();
  out.base_moment = u[2];
  return out;
}

}  // namespace magvine::robot
