#pragma once
/// Calibration (issue 29, `magvine calibrate`; docs/design.md#calibration): uncertain model parameters θ of a
/// clamped rod or vine fitted to measured quantities of its equilibria under a magnet, with their uncertainty.
///
/// The experiment's protocol: in each case the magnet approaches from its rest pose along a fixed direction u
/// (distance d from the rod's base axis), the body followed from one equilibrium to the next (continuation, Newton
/// from the last state, as the body follows a magnet brought closer). Measured quantities: the chord angle
/// (base direction to base→tip chord), the bend angle (base direction to the tip tangent) or a tip coordinate at a
/// given d; and the critical distance, the d at which the chord angle first reaches a threshold (where the thesis's
/// fluid vines "deflect sharply", thesis 5.6.1).
///
/// Fit: weighted least squares Σ ((y_i(θ) − m_i)/σ_i)² over the measurements not held out, by Levenberg–Marquardt
/// (Eigen's unsupported module) in bounded parameters θ = lo + (hi − lo)(1 + sin u)/2, with the exact sensitivities
/// of the design module: dy/dθ = ∂y/∂x · dx*/dθ, H dx*/dθ = −∂g/∂θ at the equilibrium (rod_hessian_solve). ∂g/∂θ,
/// the change of the energy gradient with a material parameter at a fixed configuration, is the central difference of
/// the analytic gradient rod_gradient (each θ reshapes the whole model: radius, stiffness, fill); the critical
/// distance d* (chord angle a(x*(d, θ)) = a_c) has dd*/dθ = −(∂a/∂θ)/(∂a/∂d), which at a snap (a fold of the
/// branch, where H turns singular) tends to the fold's own sensitivity −φᵀ∂g/∂θ / φᵀ∂g/∂d (φ the null vector).
///
/// Uncertainty (Gauss–Newton): C = (JᵀWJ)⁻¹ with W = diag(1/σ_i²) at the fit, J = dy/dθ; a held-out quantity is
/// predicted with the standard deviation √(j C jᵀ) (j its row), and its z-score (prediction − measurement) /
/// √(σ² + j C jᵀ) says whether the model and its fit explain it.

#include <functional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/rod.hpp"

namespace magvine::design {

/// One uncertain parameter [SI].
struct CalibrationParameter {
  std::string name;
  double start = 0.0;
  double lower = 0.0;
  double upper = 0.0;
};

enum class Observable { chord_angle, bend_angle, tip_x, tip_y, tip_z, critical_distance };

/// One measured quantity [SI: m, rad].
struct Measurement {
  std::size_t case_index = 0;
  Observable observable = Observable::chord_angle;
  double distance = 0.0;  ///< the magnet's distance d [m] (not for critical_distance)
  double value = 0.0;
  double sigma = 0.0;    ///< its standard deviation (> 0)
  bool holdout = false;  ///< predicted, not fitted
};

/// One configuration of the experiment (a body; several measurements share it): the rod at parameters θ (base pose,
/// gravity and solver set) and one magnet whose rest pose starts the approach.
struct CalibrationCase {
  std::string label;
  std::function<robot::RodModel(const VecX& theta)> model;
  magnetics::FieldModel magnet;   ///< one source
  Vec3 approach = Vec3::UnitX();  ///< u: the magnet sits at rest position + (d − d0) u (unit)
  double start_distance = 0.0;    ///< d0, the rest pose's distance [m]
  double step = 4e-3;             ///< the continuation's largest step in d [m]
  double closest = 0.0;           ///< the critical distance's search ends here [m]
  double critical_angle = 0.0;    ///< a_c [rad]
  robot::RodSolveOptions solver;
};

struct CalibrationProblem {
  std::vector<CalibrationParameter> parameters;
  std::vector<CalibrationCase> cases;
  std::vector<Measurement> measurements;
};

/// The model's value of every measurement at θ and, with `jacobian`, dy/dθ (one row per measurement). A critical
/// distance not reached before `closest` reads as `closest` with a zero row and `reached` false. Throws
/// NumericalError when an equilibrium of the approach fails.
struct Predictions {
  VecX values;
  MatX jacobian;
  std::vector<bool> reached;  ///< per measurement: false for a critical distance never reached
  int equilibria = 0;         ///< equilibria solved (continuation steps and bisection)
};
Predictions predict(const CalibrationProblem& problem, const VecX& theta, bool jacobian);

struct CalibrationOptions {
  int max_iterations = 50;
  /// Called after every iteration: iterations so far, the weighted residual norm χ = √Σ((y − m)/σ)².
  std::function<void(int, double)> progress;
};

struct CalibrationResult {
  VecX theta;               ///< the fit [SI]
  VecX sigma;               ///< √diag C (infinite for a direction the fitted measurements do not see)
  MatX covariance;          ///< C
  Predictions predictions;  ///< at the fit, every measurement (held out included), with the Jacobian
  VecX prediction_sigma;    ///< √(j C jᵀ) per measurement
  double chi2 = 0.0;        ///< Σ((y − m)/σ)² over the fitted measurements
  int fitted = 0;           ///< measurements fitted
  int iterations = 0;
  int evaluations = 0;  ///< predictions (each a continuation per case)
  int equilibria = 0;
  double runtime_s = 0.0;
  bool converged = false;
  std::string message;
  /// χ after every iteration (the first: at the start).
  std::vector<double> history;
};

/// Checks the problem (bounds ordered with the start inside, ≥ 1 fitted measurement, positive σ, distances within
/// the approach); InputError naming `where` otherwise.
void check_calibration_problem(const CalibrationProblem& problem, const std::string& where);

/// Fits θ (Levenberg–Marquardt from the parameters' starts) and reports its uncertainty and the held-out
/// predictions.
CalibrationResult calibrate(const CalibrationProblem& problem, const CalibrationOptions& options = {});

/// The observable's name in files: chord_angle, bend_angle (degrees there), tip_x, tip_y, tip_z,
/// critical_distance (file length units).
const char* observable_name(Observable o);

}  // namespace magvine::design
