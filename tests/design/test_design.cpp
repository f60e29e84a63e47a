// Computational design (issue 29): the exact design gradient against finite differences, the designs against
// targets made by the forward model, the Bayesian baseline on the same problem, and bad problems.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <random>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/design/design.hpp"
#include "magvine/magnetics/field_function.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/studies/design_study.hpp"

namespace magvine::design {
namespace {

/// The thesis's A.1.5.1 catheter (studies::thesis_catheter_problem): 40 mm × Ø4 mm, 5 sections, NdFeB–silicone as the
/// bundled rod scene (G = 120 kPa, Br = 0.125 T), 40 edges, clamped along x, in a fixed uniform 20 mT field along y,
/// aimed at 9 points of the straight rod.
DesignProblem catheter_problem() {
  return studies::thesis_catheter_problem();
}

/// The rod's shape under design d: its forward model's equilibrium from straight; none when that solve fails.
std::optional<std::vector<Vec3>> shape_of(const DesignProblem& p, const Design& d) {
  DesignObjective o(p);
  const robot::RodModel m = o.model_of(d);
  robot::RodState s = robot::straight_rod(m);
  if (!robot::solve_rod_statics(m, o.field_of(d), s, p.solver).converged) return std::nullopt;
  return o.points_on(s);
}

/// A target the rod reaches: the forward model's shape for a random design (seeded).
std::vector<Vec3> reachable_target(DesignProblem& p, std::uint64_t seed) {
  const std::optional<std::vector<Vec3>> shape = shape_of(p, random_design(p, seed));
  EXPECT_TRUE(shape.has_value());
  return shape.value_or(std::vector<Vec3>{});
}

/// Thesis-like arbitrary targets: a curve integrated from its curvature vector (studies::curve_target).
std::vector<Vec3> curve(double length, int points, const std::function<Vec3(double)>& curvature) {
  return studies::curve_target(length, points, curvature);
}

/// Central differences of J and of the residuals along parameter i, step 1e-6 (rad, T or m).
constexpr double kStep = 1e-6;
double difference_of_j(DesignObjective& o, const VecX& x, int i) {
  VecX a = x;
  VecX b = x;
  a[i] += kStep;
  b[i] -= kStep;
  return (o.evaluate(a, nullptr) - o.evaluate(b, nullptr)) / (2.0 * kStep);
}
bool difference_of_residuals(DesignObjective& o, const VecX& x, int i, VecX& out) {
  VecX a = x;
  VecX b = x;
  a[i] += kStep;
  b[i] -= kStep;
  VecX ra;
  VecX rb;
  if (!o.residuals(a, ra, nullptr) || !o.residuals(b, rb, nullptr)) return false;
  out = (ra - rb) / (2.0 * kStep);
  return true;
}

TEST(Design, GradientMatchesFiniteDifferences) {
  // Every parameter kind: section directions, free magnitudes and a free field. J is smooth in p; central differences
  // of step 1e-6 rad (or 1e-6 T) have a truncation error ~1e-12 relative and, with equilibria solved to a scaled
  // gradient of 1e-13, a round-off far below the 1e-5 relative the issue asks.
  DesignProblem p = catheter_problem();
  p.solver.tolerance = 1e-13;
  p.spec.remanence_bounds = std::make_pair(0.0, 0.2);
  p.spec.field_max = 0.010;
  p.field = nullptr;
  p.spec.target = reachable_target(p, 11);
  for (Vec3& t : p.spec.target) t += Vec3(0.0, 0.001, 0.0005);  // off the reachable shape: a non-zero gradient
  DesignObjective o(p);
  const VecX x = o.parameters_of(random_design(p, 5));
  VecX g;
  const double j = o.evaluate(x, &g);
  ASSERT_TRUE(std::isfinite(j));
  for (int i = 0; i < o.parameters(); ++i) {
    EXPECT_NEAR(g[i], difference_of_j(o, x, i), 1e-5 * g.cwiseAbs().maxCoeff()) << "parameter " << i;
  }
}

TEST(Design, ResidualJacobianMatchesFiniteDifferences) {
  // The forward sensitivities (one back-substitution per parameter) against central differences of the residuals;
  // the same steps and tolerance as the adjoint gradient above.
  DesignProblem p = catheter_problem();
  p.solver.tolerance = 1e-13;
  p.spec.remanence_bounds = std::make_pair(0.05, 0.2);
  p.spec.field_max = 0.010;
  p.field = nullptr;
  p.spec.target = reachable_target(p, 12);
  DesignObjective o(p);
  const VecX x = o.parameters_of(random_design(p, 6));
  VecX r;
  MatX jac;
  ASSERT_TRUE(o.residuals(x, r, &jac));
  EXPECT_NEAR(r.squaredNorm(), o.evaluate(x, nullptr), 1e-12 * r.squaredNorm());  // |r|² = J
  for (int i = 0; i < o.parameters(); ++i) {
    VecX fd;
    ASSERT_TRUE(difference_of_residuals(o, x, i, fd));
    EXPECT_LE((jac.col(i) - fd).norm(), 1e-5 * jac.norm()) << "parameter " << i;
  }
}

TEST(Design, ReachableTargetsAreFoundWithinHalfAMillimetre) {
  // Targets the forward model made from random profiles (thesis A.1.5.1's catheter, 9 points every 5 mm), designed from
  // another random profile: the exact design exists, so Levenberg–Marquardt should reach it; the issue asks RMS ≤ 0.5
  // mm within 20 iterations. (Measured 2026-12-04 over 12 targets: 0.5 mm after 1–9 iterations, final RMS ≤ 0.012 mm.)
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    DesignProblem p = catheter_problem();
    p.spec.target = reachable_target(p, 100 + seed);
    const DesignResult r = least_squares_design(p, random_design(p, seed), {});
    int iterations = -1;
    for (const DesignResult::Step& s : r.history) {
      if (s.best_rms <= 0.5e-3) {
        iterations = s.iteration;
        break;
      }
    }
    EXPECT_LE(r.rms, 0.5e-3) << "seed " << seed;
    EXPECT_GE(iterations, 0) << "seed " << seed;
    EXPECT_LE(iterations, 20) << "seed " << seed;
    // The reported shape is the design's equilibrium from the straight rod (what `magvine run` solves).
    DesignObjective o(p);
    const robot::RodModel m = o.model_of(r.design);
    robot::RodState s = robot::straight_rod(m);
    ASSERT_TRUE(robot::solve_rod_statics(m, o.field_of(r.design), s, p.solver).converged);
    EXPECT_LT((s.tip() - r.state.tip()).norm(), 1e-9);
  }
}

TEST(Design, ArbitraryShapesWithinTwoMillimetres) {
  // Thesis-like arbitrary targets (A.1.5.1: "RMS below 2 mm"), not made by the model: an S in the field's plane
  // (±90° over each half) and a 3D hook (90° in the plane, then 90° out of it), from four random starts each.
  // Measured 2026-12-04: S 0.70 mm from every start, hook 0.45–0.84 mm.
  const double l = 0.040;
  const std::vector<std::function<Vec3(double)>> shapes = {
      [l](double s) { return Vec3(0, (s < l / 2 ? 1.0 : -1.0) * kPi / l, 0); },
      [l](double s) { return s < l / 2 ? Vec3(0, kPi / l, 0) : Vec3(0, 0, kPi / l); },
  };
  for (std::size_t shape = 0; shape < shapes.size(); ++shape) {
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      DesignProblem p = catheter_problem();
      p.spec.target = curve(l, 9, shapes[shape]);
      const DesignResult r = least_squares_design(p, random_design(p, seed), {});
      EXPECT_LT(r.rms, 2e-3) << "shape " << shape << " seed " << seed;
    }
  }
}

TEST(Design, BadProblemsNameTheirField) {
  const auto message = [](const DesignProblem& p) {
    try {
      check_design_problem(p, "d.yaml");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  DesignProblem ok = catheter_problem();
  EXPECT_EQ(message(ok), "accepted");
  DesignProblem far = ok;
  far.spec.target.back() = Vec3(0.045, 0, 0);  // the tip 45 mm from the base of a 40 mm rod
  EXPECT_NE(message(far).find("design.target.points[8]: is 45.00 mm"), std::string::npos) << message(far);
  DesignProblem stretched = ok;
  stretched.spec.target[4] = Vec3(0.020, 0.004, 0);  // 6.4 mm from its neighbours, 5 mm of rod between them
  EXPECT_NE(message(stretched).find("the wrong length"), std::string::npos) << message(stretched);
  DesignProblem nan = ok;
  nan.spec.target[2].y() = std::nan("");
  EXPECT_NE(message(nan).find("design.target.points[2]: must be finite"), std::string::npos) << message(nan);
  DesignProblem bounds = ok;
  bounds.spec.remanence_bounds = std::make_pair(0.2, 0.1);
  EXPECT_NE(message(bounds).find("exclude every design"), std::string::npos) << message(bounds);
  DesignProblem sections = ok;
  sections.spec.sections = 41;
  EXPECT_NE(message(sections).find("design.sections"), std::string::npos) << message(sections);
  DesignProblem unmoved = ok;
  unmoved.field = nullptr;
  EXPECT_NE(message(unmoved).find("nothing would move the rod"), std::string::npos) << message(unmoved);
}

TEST(Design, UnreachableTargetEndsWithTheBestDesignAndItsDistance) {
  // A target the field cannot make (a bend in the x–z plane needs a torque about the field's axis y, which m × B never
  // has): the design ends, reports how far it is, and its shape is its equilibrium.
  DesignProblem p = catheter_problem();
  p.spec.target = curve(0.040, 9, [](double) { return Vec3(0, 0, kPi / 0.040); });
  const DesignResult r = least_squares_design(p, random_design(p, 1), {});
  EXPECT_GT(r.rms, 2e-3);
  EXPECT_TRUE(std::isfinite(r.rms));
  // Its shape is its design's equilibrium, solved again from the straight rod here, and its RMS that shape's.
  DesignObjective o(p);
  const robot::RodModel m = o.model_of(r.design);
  robot::RodState s = robot::straight_rod(m);
  ASSERT_TRUE(robot::solve_rod_statics(m, o.field_of(r.design), s, p.solver).converged);
  EXPECT_LT((s.tip() - r.state.tip()).norm(), 1e-9);
  const std::vector<Vec3> x = o.points_on(s);
  double sum = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) sum += (x[k] - p.spec.target[k]).squaredNorm();
  EXPECT_NEAR(r.rms, std::sqrt(sum / static_cast<double>(x.size())), 1e-9);
}

/// The A.1.5.1 catheter under an EPM whose position is designed: the thesis EPM (N52, Ø101.6 × 101.6 mm, J 1.48 T) as
/// `kind` (an exact cylinder or a dipole), axis along y, 150 mm below the rod's middle, free to move in a 100 mm box.
DesignProblem magnet_problem(bool cylinder) {
  DesignProblem p = catheter_problem();
  magnetics::FieldModel magnets;
  const magnetics::Pose pose{Vec3(0.020, -0.150, 0.0), Mat3::Identity()};  // the source frame's z along world z
  const double j = 1.48;
  const double d = 0.1016;
  if (cylinder) {
    magnets.add(magnetics::CylinderMagnet(0.5 * d, d, Vec3(0.0, j, 0.0)), pose, "epm");
  } else {
    magnets.add(magnetics::DipoleSource{Vec3(0.0, j / kMu0 * kPi * 0.25 * d * d * d, 0.0)}, pose, "epm");
  }
  p.field = magnetics::field_function(magnets, magnets.rest_poses);
  p.magnet = DesignProblem::MagnetPosition{magnets, 0, Vec3(-0.030, -0.200, -0.050), Vec3(0.070, -0.100, 0.050)};
  return p;
}

TEST(Design, MagnetPositionSensitivityMatchesFiniteDifferences) {
  // The EPM's position as a design variable: dx*/dp from the magnetic term's own Hessian blocks (the field's curvature
  // in closed form for the dipole, from differences of the exact cylinder's gradient as in the Newton Hessian) against
  // central differences (1e-6 m) of equilibria polished by three more Newton steps. Unpolished, the solver's stop (a
  // Newton step under 1e-10 L) left the dipole's equilibrium 7.7e-8 m short, and the differences 1e-4 off (2026-12-04).
  // Then the adjoint gradient against the forward sensitivities (dJ/dp = 2 rᵀ dr/dp).
  for (const bool cylinder : {false, true}) {
    DesignProblem p = magnet_problem(cylinder);
    p.solver.tolerance = 1e-13;
    p.spec.target = reachable_target(p, 21);
    for (Vec3& t : p.spec.target) t += Vec3(0.0, 0.001, 0.0);
    DesignObjective o(p);
    Design d = random_design(p, 8);
    d.magnet_position = Vec3(0.030, -0.140, 0.010);
    const robot::RodModel m = o.model_of(d);
    const auto solve = [&](const Design& at) {
      const robot::RodField f = o.field_of(at);
      robot::RodState s = robot::straight_rod(m);
      EXPECT_TRUE(robot::solve_rod_statics(m, f, s, p.solver).converged);
      for (int it = 0; it < 3; ++it) {
        const VecX step = -robot::rod_hessian_solve(m, f, s, robot::rod_gradient(m, f, s))->col(0);
        for (int j = 0; j < m.edges; ++j) {
          s.x[static_cast<std::size_t>(j) + 1] += step.segment<3>(6 * j);
          const Vec3 phi = step.segment<3>(6 * j + 3);
          if (phi.norm() > 0.0) {
            s.frames[static_cast<std::size_t>(j)] = Eigen::AngleAxisd(phi.norm(), phi.normalized()).toRotationMatrix() *
                                                    s.frames[static_cast<std::size_t>(j)];
          }
        }
      }
      return s;
    };
    const robot::RodState s = solve(d);
    magnetics::FieldModel one;
    one.add(p.magnet->magnets.sources[0], p.magnet->magnets.rest_poses[0]);
    magnetics::Pose pose = p.magnet->magnets.rest_poses[0];
    pose.position = *d.magnet_position;
    const MatX sens = robot::rod_field_translation_sensitivity(m, magnetics::field_function(one, {pose}), s);
    const MatX dx = *robot::rod_hessian_solve(m, o.field_of(d), s, -sens);
    for (int k = 0; k < 3; ++k) {
      const double h = 1e-6;
      Design a = d;
      Design b = d;
      (*a.magnet_position)[k] += h;
      (*b.magnet_position)[k] -= h;
      const robot::RodState sa = solve(a);
      const robot::RodState sb = solve(b);
      double worst = 0.0;
      double largest = 0.0;
      for (int i = 1; i <= m.edges; ++i) {
        const auto iu = static_cast<std::size_t>(i);
        const Vec3 fd = (sa.x[iu] - sb.x[iu]) / (2.0 * h);
        worst = std::max(worst, (fd - dx.block<3, 1>(6 * (i - 1), k)).norm());
        largest = std::max(largest, fd.norm());
      }
      EXPECT_LT(worst, 1e-5 * largest) << (cylinder ? "cylinder" : "dipole") << ", coordinate " << k;
    }
    const VecX x = o.parameters_of(d);
    VecX g;
    VecX r;
    MatX jac;
    ASSERT_TRUE(std::isfinite(o.evaluate(x, &g)));
    ASSERT_TRUE(o.residuals(x, r, &jac));
    const VecX forward = 2.0 * jac.transpose() * r;
    EXPECT_LT((g - forward).norm(), 1e-9 * g.norm()) << (cylinder ? "cylinder" : "dipole");
    // And the objective's own gradient over the magnet's coordinates against central differences of J, for the exact
    // cylinder, whose equilibria the solver brings close enough for that (3e-7 measured; see above for the dipole).
    if (!cylinder) continue;
    const int at = o.parameters() - 3;
    for (int i = at; i < o.parameters(); ++i) {
      EXPECT_NEAR(g[i], difference_of_j(o, x, i), 1e-5 * g.segment<3>(at).cwiseAbs().maxCoeff())
          << "coordinate " << i - at;
    }
  }
}

TEST(Design, TheMagnetIsPlacedWhereItBendsTheRodOntoTheTarget) {
  // A target the rod takes with its own profile under the EPM at a known place (the exact cylinder, 30 mm along x,
  // 20 mm closer and 15 mm out of plane from where the scene puts it), with one section: designing where the magnet
  // goes and that section's direction recovers the shape and the place.
  DesignProblem p = magnet_problem(true);
  p.spec.sections = 1;
  const Vec3 truth(0.050, -0.130, 0.015);
  {
    Design d = random_design(p, 4);
    d.directions = {Vec3(0.6, 0.8, 0.0)};
    d.magnet_position = truth;
    const std::optional<std::vector<Vec3>> shape = shape_of(p, d);
    ASSERT_TRUE(shape.has_value());
    p.spec.target = *shape;
  }
  DesignOptions options;
  options.starts = 2;
  const DesignResult r = multi_start_design(p, DesignMethod::least_squares, options);
  EXPECT_LT(r.rms, 0.05e-3);
  EXPECT_LT((*r.design.magnet_position - truth).norm(), 0.1e-3);
  std::printf("RMS %.4f mm, magnet at (%.2f, %.2f, %.2f) mm (truth (50, -130, 15)), %d equilibria\n", r.rms * 1e3,
              r.design.magnet_position->x() * 1e3, r.design.magnet_position->y() * 1e3,
              r.design.magnet_position->z() * 1e3, r.evaluations);
}

TEST(Design, MagnetOrientationGradientMatchesFiniteDifferencesAndTheAxisIsRecovered) {
  // The EPM's pose as a design variable: the thesis EPM with its moment along its axis, 150 mm below
  // the rod's middle pointing up, its centre in a 100 mm box and its axis free. The objective's gradient over the axis
  // angles (∂g/∂(θ_a, φ_a) from central differences of the analytic gradient, design.hpp) against central differences
  // of J (1e-6 rad), to 1e-5 of the largest; and the adjoint against the forward sensitivities. Then a target made by
  // the forward model with the magnet turned 25° about x and moved (one section): the design recovers the axis.
  // The gradient check takes the EPM as its dipole, whose field curvature (in the Newton Hessian) is closed-form: with
  // the exact cylinder's, from forward differences of its gradient, the adjoint of the minimal build (no FMA kernels)
  // sat 1.7e-5 from differences of J, the full build's 1e-9 (2026-12-04). The recovery takes the exact cylinder.
  const auto problem_with = [](bool cylinder) {
    DesignProblem q = catheter_problem();
    q.spec.sections = 1;
    magnetics::FieldModel magnets;
    const magnetics::Pose pose = magnetics::Pose::from_axis(Vec3(0.020, -0.150, 0.0), Vec3::UnitY());
    if (cylinder) {
      magnets.add(magnetics::CylinderMagnet(0.0508, 0.1016, Vec3(0.0, 0.0, 1.48)), pose, "epm");
    } else {
      magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 1.48 / kMu0 * kPi * 0.0508 * 0.0508 * 0.1016)}, pose, "epm");
    }
    q.field = magnetics::field_function(magnets, magnets.rest_poses);
    q.magnet =
        DesignProblem::MagnetPosition{magnets, 0, Vec3(-0.030, -0.200, -0.050), Vec3(0.070, -0.100, 0.050), true};
    return q;
  };
  DesignProblem p = problem_with(false);
  const Vec3 truth_position(0.040, -0.140, 0.010);
  const Vec3 truth_axis = Eigen::AngleAxisd(25.0 * kDegToRad, Vec3::UnitX()) * Vec3::UnitY();
  // The truth's shape, the target.
  const auto aim_at_truth = [&](DesignProblem& q) {
    Design d = random_design(q, 4);
    d.directions = {Vec3(0.6, 0.8, 0.0)};
    d.magnet_position = truth_position;
    d.magnet_axis = truth_axis;
    const std::optional<std::vector<Vec3>> shape = shape_of(q, d);
    ASSERT_TRUE(shape.has_value());
    q.spec.target = *shape;
  };
  aim_at_truth(p);
  if (HasFatalFailure()) return;
  // Equilibria to the round-off floor: the adjoint assumes g = 0, and the default stop (a Newton step under 1e-10 L)
  // left the minimal build's adjoint 1.7e-5 off (2026-12-04), as MagnetPositionSensitivityMatchesFiniteDifferences
  // found for the dipole.
  p.solver.tolerance = 1e-13;
  DesignObjective o(p);
  ASSERT_EQ(o.parameters(), 7);
  EXPECT_TRUE(o.is_bounded(2) && o.is_bounded(4) && !o.is_bounded(5) && !o.is_bounded(6));
  Design d = random_design(p, 3);
  d.directions = {Vec3(0.5, 0.7, 0.2).normalized()};
  d.magnet_position = Vec3(0.030, -0.150, 0.0);
  d.magnet_axis = Vec3(0.2, 0.95, 0.1).normalized();
  const VecX x = o.parameters_of(d);
  VecX g;
  VecX r;
  MatX jac;
  ASSERT_TRUE(std::isfinite(o.evaluate(x, &g)));
  ASSERT_TRUE(o.residuals(x, r, &jac));
  EXPECT_LT((g - 2.0 * jac.transpose() * r).norm(), 1e-9 * g.norm());
  const double scale = g.tail<2>().cwiseAbs().maxCoeff();
  for (int i = 5; i < 7; ++i) {
    const double fd = difference_of_j(o, x, i);
    std::printf("  axis angle %d: adjoint %.9g, differences %.9g\n", i - 5, g[i], fd);
    EXPECT_NEAR(g[i], fd, 1e-5 * scale) << "axis angle " << i - 5;
  }
  p = problem_with(true);
  aim_at_truth(p);
  if (HasFatalFailure()) return;
  // Shape alone does not fix the pose (a first run with the centre free found RMS 0.0015 mm with the magnet 59 mm and
  // 47° from the truth: the rod reads only the field along itself): with the centre where it was, the axis is
  // recovered.
  p.magnet->min = truth_position;
  p.magnet->max = truth_position;
  DesignOptions options;
  options.starts = 2;
  const DesignResult result = multi_start_design(p, DesignMethod::least_squares, options);
  const double axis_error = std::acos(std::clamp(result.design.magnet_axis->dot(truth_axis), -1.0, 1.0)) / kDegToRad;
  std::printf("  RMS %.4f mm, axis %.2f° from the truth, centre %.3f mm from it, %d equilibria\n", result.rms * 1e3,
              axis_error, (*result.design.magnet_position - truth_position).norm() * 1e3, result.evaluations);
  EXPECT_LT(result.rms, 0.05e-3);
  EXPECT_LT(axis_error, 1.0);
}

TEST(Design, TheFieldContinuationReachesStrongFieldTargetsAsThePlainDesignDoes) {
  // The continuation in the field (DesignOptions::field_stages): the A.1.5.1 catheter in a strong uniform field nearly
  // against its axis (−60 mT along x, 4 mT along y), where large deflections and several equilibria are possible; the
  // shapes of random designs (seeds 100 and 102) as targets, four starts each, with and without four field stages.
  // Measured over twelve such targets (seeds 100–105 at −30 and −60 mT, 2026-12-04): the plain design brought 45 of 48
  // starts within 0.5 mm, the continuation 43, at 3–5 times the equilibria. Asserted here: both reach these two targets
  // (best of four starts under 0.05 mm), and each stage's design starts the next (the equilibria add up).
  DesignProblem p = catheter_problem();
  magnetics::FieldModel f;
  f.add(magnetics::UniformSource{Vec3(-0.060, 0.004, 0.0)}, magnetics::Pose{}, "uniform");
  p.field = magnetics::field_function(f, f.rest_poses);
  for (const std::uint64_t seed : {100u, 102u}) {
    DesignProblem q = p;
    q.spec.target = reachable_target(q, seed);
    DesignOptions plain;
    plain.starts = 4;
    plain.seed = 7;
    DesignOptions continued = plain;
    continued.field_stages = 4;
    const DesignResult a = multi_start_design(q, DesignMethod::least_squares, plain);
    const DesignResult b = multi_start_design(q, DesignMethod::least_squares, continued);
    std::printf("  target %lu: plain %.4f mm (%d equilibria), continuation %.4f mm (%d equilibria)\n",
                static_cast<unsigned long>(seed), a.rms * 1e3, a.evaluations, b.rms * 1e3, b.evaluations);
    EXPECT_LT(a.rms, 0.05e-3);
    EXPECT_LT(b.rms, 0.05e-3);
    EXPECT_GT(b.evaluations, a.evaluations);
    EXPECT_NE(b.message.find("field continuation, 4 stages"), std::string::npos) << b.message;
  }
}

/// Thesis A.1.5.2's catheter: 56 mm × Ø3 mm, five sections, pushed out along x in eight steps with a free field of
/// at most 10 mT per step; the path as 17 points every 3.5 mm.
DesignProblem insertion_problem(const std::function<Vec3(double)>& path) {
  DesignProblem p;
  p.model = robot::circular_rod(0.056, 0.003, 120e3, 1882.0, 56);
  p.area = 0.25 * kPi * 0.003 * 0.003;
  p.spec.sections = 5;
  p.spec.remanence = 0.125;
  p.spec.field_max = 0.010;
  p.insertion_steps = 8;
  p.spec.target = curve(0.056, 17, path);
  return p;
}

TEST(Design, InsertionGradientMatchesFiniteDifferences) {
  // The follow-the-leader objective: eight configurations of growing length, the shared sections and a field per
  // step; the adjoint gradient and the Jacobian against central differences, as for the static design.
  DesignProblem p = insertion_problem([](double s) { return Vec3(0, s < 0.028 ? 0.0 : kPi / 0.056, 0); });
  p.solver.tolerance = 1e-13;
  DesignObjective o(p);
  Design d = random_design(p, 3);
  for (std::size_t f = 0; f < d.fields.size(); ++f) d.fields[f] = 0.006 * Vec3(0.3, 1.0, 0.1 * f).normalized();
  const VecX x = o.parameters_of(d);
  VecX g;
  VecX r;
  MatX jac;
  ASSERT_TRUE(std::isfinite(o.evaluate(x, &g)));
  ASSERT_TRUE(o.residuals(x, r, &jac));
  EXPECT_EQ(o.parameters(), 5 * 2 + 8 * 3);
  for (int i = 0; i < o.parameters(); ++i) {
    EXPECT_NEAR(g[i], difference_of_j(o, x, i), 1e-5 * g.cwiseAbs().maxCoeff()) << "parameter " << i;
    VecX fd;
    ASSERT_TRUE(difference_of_residuals(o, x, i, fd));
    EXPECT_LE((jac.col(i) - fd).norm(), 1e-5 * jac.norm()) << "parameter " << i;
  }
}

TEST(Design, FollowTheLeaderWithinOneMillimetre) {
  // A.1.5.2 (the thesis: exit error 3 mm; the issue: RMS ≤ 1 mm over all insertion steps): a J (28 mm straight, then
  // 90° in the x–y plane) and a 3D bend (45° in that plane, then 45° out of it), four random starts each.
  // Measured 2026-12-04: J 0.25 mm, 3D bend 0.20 mm (single starts ranged 0.05–4 mm: local minima).
  const double l = 0.056;
  const std::vector<std::function<Vec3(double)>> paths = {
      [l](double s) { return s < l / 2 ? Vec3(0, 0, 0) : Vec3(0, kPi / l, 0); },
      [l](double s) { return s < l / 2 ? Vec3(0, 0.5 * kPi / l, 0) : Vec3(0, 0, 0.5 * kPi / l); },
  };
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const DesignProblem p = insertion_problem(paths[i]);
    DesignOptions options;
    options.starts = 4;
    const DesignResult r = multi_start_design(p, DesignMethod::least_squares, options);
    EXPECT_LE(r.rms, 1e-3) << "path " << i;
    std::printf("path %zu: rms %.3f mm max %.3f mm, %d equilibria, %.2f s\n", i, r.rms * 1e3, r.max_error * 1e3,
                r.evaluations, r.runtime_s);
    ASSERT_EQ(r.states.size(), 8u);
    for (const Vec3& b : r.design.fields) EXPECT_LE(b.norm(), 0.010 * (1.0 + 1e-12));
  }
}

}  // namespace
}  // namespace magvine::design
