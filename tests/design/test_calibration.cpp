// Calibration (issue 29): the sensitivities of the measured quantities against finite differences, parameters
// recovered from measurements the model made, the Gauss–Newton uncertainty against the scatter of fits to noisy
// measurements, and bad problems.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/design/calibration.hpp"
#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::design {
namespace {

/// The thesis's fluid-vine deflection setup (5.6.1): a 50 mm vine of diameter `diameter` standing against gravity,
/// the Ø101.6 mm N52 EPM at its tip's height with its axis at the vine, approaching along x from 300 mm. θ =
/// (iron volume fraction, film modulus [Pa]); below 3.2 MPa the film's stretch bursts the Ø4 mm vine at 35 kPa.
/// A vine standing up: its base along +z, the base normal along x (towards the magnet), gravity along −z.
robot::RodModel upright(const robot::VineParameters& v) {
  robot::RodModel m = robot::vine_rod(v);
  m.base_frame.col(0) = Vec3::UnitZ();
  m.base_frame.col(1) = Vec3::UnitX();
  m.base_frame.col(2) = Vec3::UnitZ().cross(Vec3::UnitX());
  m.gravity = Vec3(0.0, 0.0, -9.81);
  return m;
}

CalibrationCase fluid_vine_case(double diameter, double pressure) {
  CalibrationCase c;
  c.label = "Ø" + std::to_string(diameter * 1e3) + " mm";
  c.model = [diameter, pressure](const VecX& theta) {
    robot::VineParameters v = robot::thesis_fluid_vine(50e-3, 25);
    v.radius = 0.5 * diameter;
    v.pressure = pressure;
    v.volume_fraction = theta[0];
    v.wall.modulus = theta[1];
    return upright(v);
  };
  c.magnet.add(magnetics::CylinderMagnet(0.0508, 0.1016, Vec3(0.0, 0.0, 1.48)),
               magnetics::Pose::from_axis(Vec3(0.3, 0.0, 0.05), -Vec3::UnitX()), "EPM");
  c.approach = Vec3::UnitX();
  c.start_distance = 0.3;
  c.step = 4e-3;
  c.closest = 0.104;
  c.critical_angle = 20.0 * kDegToRad;
  return c;
}

std::vector<CalibrationParameter> fluid_parameters() {
  return {{.name = "fill.volume_fraction", .start = 0.23, .lower = 0.02, .upper = 0.5},
          {.name = "wall.youngs_modulus", .start = 10e6, .lower = 4e6, .upper = 100e6}};
}

TEST(Calibration, SensitivitiesMatchFiniteDifferences) {
  CalibrationProblem p;
  p.parameters = fluid_parameters();
  p.cases.push_back(fluid_vine_case(4e-3, 35e3));
  p.measurements = {{.observable = Observable::chord_angle, .distance = 0.18, .sigma = 1.0},
                    {.observable = Observable::bend_angle, .distance = 0.15, .sigma = 1.0},
                    {.observable = Observable::tip_x, .distance = 0.15, .sigma = 1.0},
                    {.observable = Observable::critical_distance, .sigma = 1.0}};
  const VecX theta = VecX{{0.2, 12e6}};
  const Predictions y = predict(p, theta, true);
  for (Eigen::Index i = 0; i < theta.size(); ++i) {
    // Central differences at steps h and 2h, Richardson-extrapolated (truncation O(h⁴)), h = 2e-3 θ: large enough that
    // the equilibria's own scatter (solved to the stiff stretch's round-off floor) stays below 1e-5 of each difference.
    // The critical distance scatters more, ~1e-9 m (the bisection's end state is an equilibrium like the others, and
    // the search divides its angle error by the angle's slope), so it takes plain central differences at h = 1e-2 θ
    // (truncation ~1e-5 relative here) and is held to 1e-4.
    const auto central = [&](double h) {
      VecX a = theta;
      VecX b = theta;
      a[i] += h;
      b[i] -= h;
      return VecX((predict(p, a, false).values - predict(p, b, false).values) / (2.0 * h));
    };
    const double h = 2e-3 * theta[i];
    const VecX fd = (4.0 * central(h) - central(2.0 * h)) / 3.0;
    const VecX wide = central(1e-2 * theta[i]);
    for (Eigen::Index k = 0; k < fd.size(); ++k) {
      const bool critical = p.measurements[static_cast<std::size_t>(k)].observable == Observable::critical_distance;
      const double reference = critical ? wide[k] : fd[k];
      const double relative = critical ? 1e-4 : 1e-5;
      std::printf("  θ%td measurement %td: exact %.9g, differences %.9g\n", i, k, y.jacobian(k, i), reference);
      EXPECT_NEAR(y.jacobian(k, i), reference, relative * std::abs(reference)) << "θ" << i << ", measurement " << k;
    }
  }
}

/// Measurements made by the model at θ_true: chord angles along the approach and the critical distance.
CalibrationProblem synthetic_problem(const VecX& truth, bool with_critical) {
  CalibrationProblem p;
  p.parameters = fluid_parameters();
  p.cases.push_back(fluid_vine_case(4e-3, 35e3));
  for (const double d : {0.26, 0.22, 0.2, 0.18, 0.15}) {
    p.measurements.push_back({.observable = Observable::chord_angle, .distance = d, .sigma = 0.5 * kDegToRad});
  }
  if (with_critical) p.measurements.push_back({.observable = Observable::critical_distance, .sigma = 2e-3});
  const Predictions y = predict(p, truth, false);
  for (std::size_t i = 0; i < p.measurements.size(); ++i)
    p.measurements[i].value = y.values[static_cast<Eigen::Index>(i)];
  return p;
}

TEST(Calibration, RecoversTheParametersThatMadeTheMeasurements) {
  // The fluid vine with 18 % iron and a 14 MPa film, fitted from the 23 % and 10 MPa start; exact data, so the fit
  // must land on the truth to the equilibria's precision (1e-4 relative: the fit's own tolerance is 1e-10 in χ²).
  const VecX truth{{0.18, 14e6}};
  CalibrationProblem p = synthetic_problem(truth, true);
  p.measurements.push_back({.observable = Observable::tip_x, .distance = 0.12, .sigma = 1e-3, .holdout = true});
  p.measurements.back().value = predict(p, truth, false).values.tail(1)[0];
  const CalibrationResult r = calibrate(p);
  std::printf(
      "  fit %.6g, %.6g Pa (truth 0.18, 1.4e7) ± %.3g, %.3g in %d iterations, %d evaluations, %d equilibria, "
      "%.2f s; %s\n",
      r.theta[0], r.theta[1], r.sigma[0], r.sigma[1], r.iterations, r.evaluations, r.equilibria, r.runtime_s,
      r.message.c_str());
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_NEAR(r.theta[0], truth[0], 1e-4 * truth[0]);
  EXPECT_NEAR(r.theta[1], truth[1], 1e-4 * truth[1]);
  EXPECT_LT(r.chi2, 1e-6);
  // The held-out tip position is predicted as the truth makes it.
  const Eigen::Index last = r.predictions.values.size() - 1;
  EXPECT_NEAR(r.predictions.values[last], p.measurements.back().value, 1e-7);
  EXPECT_GT(r.prediction_sigma[last], 0.0);
}

TEST(Calibration, CovarianceMatchesTheScatterOfNoisyFits) {
  // Gauss–Newton's C = (JᵀWJ)⁻¹ is the covariance of the fit when the measurements scatter by σ and the model is
  // nearly linear over that scatter: 24 fits to the angles of synthetic_problem plus N(0, σ²) noise (seeded), the
  // sample standard deviation of each parameter against √C_ii. 24 samples estimate a standard deviation to ±15 %
  // (one σ), so the bound is 40 %.
  const VecX truth{{0.18, 14e6}};
  const CalibrationProblem exact = synthetic_problem(truth, false);
  const CalibrationResult reference = calibrate(exact);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  constexpr int kFits = 24;
  std::vector<VecX> fits;
  for (int k = 0; k < kFits; ++k) {
    CalibrationProblem noisy = exact;
    for (Measurement& m : noisy.measurements) m.value += m.sigma * normal(rng);
    const CalibrationResult r = calibrate(noisy);
    ASSERT_TRUE(r.converged) << r.message;
    fits.push_back(r.theta);
  }
  for (Eigen::Index i = 0; i < 2; ++i) {
    double mean = 0.0;
    for (const VecX& f : fits) mean += f[i] / kFits;
    double var = 0.0;
    for (const VecX& f : fits) var += std::pow(f[i] - mean, 2) / (kFits - 1);
    std::printf("  θ%td: scatter of %d fits %.4g, Gauss–Newton σ %.4g\n", i, kFits, std::sqrt(var), reference.sigma[i]);
    EXPECT_NEAR(std::sqrt(var), reference.sigma[i], 0.4 * reference.sigma[i]);
  }
}

/// The thesis's skin MVR in the torque setup (4.7.1, fig 4.5B): 80 mm, Ø8 mm, vertical against gravity, its skin
/// magnetised towards the EPM, whose axis is vertical, 65 mm above the base, approaching along x from 300 mm to 132 mm
/// (d > L + R_EPM). θ = (film modulus [Pa], skin remanence [T]).
CalibrationCase skin_vine_case(double pressure) {
  CalibrationCase c;
  c.label = std::to_string(pressure * 1e-3) + " kPa";
  c.model = [pressure](const VecX& theta) {
    robot::VineParameters v = robot::thesis_skin_mvr(80e-3, 40);
    v.pressure = pressure;
    v.wall.modulus = theta[0];
    v.skin_remanence = theta[1];
    return upright(v);
  };
  c.magnet.add(magnetics::CylinderMagnet(0.0508, 0.1016, Vec3(0.0, 0.0, 1.48)),
               magnetics::Pose::from_axis(Vec3(0.3, 0.0, 0.065), Vec3::UnitZ()), "EPM");
  c.approach = Vec3::UnitX();
  c.start_distance = 0.3;
  c.step = 4e-3;
  c.closest = 0.132;
  c.critical_angle = 20.0 * kDegToRad;
  return c;
}

TEST(Calibration, SkinVineCreaseOnsetsPinTheRemanenceNotTheFilmModulus) {
  // The thesis assumes the LDPE film's modulus (0.2 GPa); fig 4.6's crease onsets against distance at 1, 6 and 12 kPa
  // would determine it, but the thesis's text gives only its model's errors against them, not the distances. What the
  // calibration recovers from such data: onsets (20° reached) and the angles 8 mm closer at 1, 3 and 6 kPa (at 12 kPa
  // the model's vine does not reach 20° before 132 mm, where the magnet would touch it), made by the model at 0.2 GPa
  // and 0.101 T, fitted from 0.1 GPa and 0.08 T. The data pin the remanence (σ ≈ 12 % at σ = 5 mm and 3°) but hardly
  // the modulus (σ ≈ 140 %: before the wall wrinkles the body is stiff whatever E is, and the onset is set by the
  // wrinkling moment πR³P/2, which has no E), so exact data land on the truth to 1e-4 in Br and only to 1e-3 in E,
  // where χ² is flat to the fit's tolerance (χ² < 1e-6 asserted).
  const VecX truth{{0.2e9, 0.101}};
  CalibrationProblem p;
  p.parameters = {{.name = "wall.youngs_modulus", .start = 0.1e9, .lower = 0.02e9, .upper = 1e9},
                  {.name = "skin.remanence", .start = 0.08, .lower = 0.02, .upper = 0.3}};
  for (const double kpa : {1.0, 3.0, 6.0}) {
    p.cases.push_back(skin_vine_case(kpa * 1e3));
    p.measurements.push_back(
        {.case_index = p.cases.size() - 1, .observable = Observable::critical_distance, .sigma = 5e-3});
  }
  Predictions made = predict(p, truth, false);
  for (std::size_t k = 0; k < 3; ++k) {
    p.measurements[k].value = made.values[static_cast<Eigen::Index>(k)];
    p.measurements.push_back({.case_index = k,
                              .observable = Observable::chord_angle,
                              .distance = p.measurements[k].value - 8e-3,
                              .sigma = 3.0 * kDegToRad});
  }
  made = predict(p, truth, false);
  for (std::size_t k = 3; k < 6; ++k) p.measurements[k].value = made.values[static_cast<Eigen::Index>(k)];
  for (std::size_t k = 0; k < 6; ++k) {
    ASSERT_TRUE(made.reached[k]);
    std::printf("  made: case %zu %s %.6g\n", p.measurements[k].case_index,
                observable_name(p.measurements[k].observable), p.measurements[k].value);
  }
  const CalibrationResult r = calibrate(p);
  std::printf("  fit E %.6g Pa ± %.3g, Br %.6g T ± %.3g in %d iterations, %d equilibria, %.2f s; %s\n", r.theta[0],
              r.sigma[0], r.theta[1], r.sigma[1], r.iterations, r.equilibria, r.runtime_s, r.message.c_str());
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.chi2, 1e-6);
  EXPECT_NEAR(r.theta[0], truth[0], 1e-3 * truth[0]);
  EXPECT_NEAR(r.theta[1], truth[1], 1e-4 * truth[1]);
  EXPECT_GT(r.sigma[0], 0.5 * truth[0]);  // what the onsets cannot tell
  EXPECT_LT(r.sigma[1], 0.2 * truth[1]);
}

TEST(Calibration, RefusesBadProblems) {
  CalibrationProblem good;
  good.parameters = fluid_parameters();
  good.cases.push_back(fluid_vine_case(4e-3, 35e3));
  good.measurements = {{.observable = Observable::chord_angle, .distance = 0.2, .value = 0.3, .sigma = 0.01}};
  EXPECT_NO_THROW(check_calibration_problem(good, "f.yaml"));
  const auto refused = [&](const std::function<void(CalibrationProblem&)>& spoil, const std::string& says) {
    CalibrationProblem p = good;
    spoil(p);
    try {
      check_calibration_problem(p, "f.yaml");
      ADD_FAILURE() << "accepted: " << says;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused([](CalibrationProblem& p) { p.parameters[0].upper = p.parameters[0].lower; }, "min < max");
  refused([](CalibrationProblem& p) { p.parameters[1].start = 1e9; }, "outside [min, max]");
  refused([](CalibrationProblem& p) { p.measurements[0].sigma = 0.0; }, "sigma must be positive");
  refused([](CalibrationProblem& p) { p.measurements[0].value = NAN; }, "not a finite number");
  refused([](CalibrationProblem& p) { p.measurements[0].distance = 0.4; }, "no farther than where the magnet starts");
  refused([](CalibrationProblem& p) { p.measurements[0].holdout = true; }, "nothing to fit");
  refused([](CalibrationProblem& p) { p.measurements[0].case_index = 3; }, "names no case");
  refused([](CalibrationProblem& p) { p.parameters.clear(); }, "no parameter to fit");
}

}  // namespace
}  // namespace magvine::design
