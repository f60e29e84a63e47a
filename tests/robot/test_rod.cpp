// The discretised rod (robot/rod.hpp): derivatives against finite differences, small loads against Euler–Bernoulli,
// large deflections against the elastica reference solver (robot/elastica.hpp), and its convergence with the node
// count.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/rod.hpp"
#include "support/rod_derivatives.hpp"

namespace magvine::robot {
namespace {

// The acceptance beam (support/rod_derivatives.hpp).
constexpr double kLength = testing::kBeamLength;
constexpr double kSide = testing::kBeamSide;
constexpr double kG = testing::kBeamShearModulus;
constexpr double kRho = testing::kBeamDensity;
constexpr double kBr = testing::kBeamRemanence;
constexpr int kEdges = 50;  // the default resolution of these tests

RodModel acceptance_rod(const Vec3& magnetisation = Vec3::UnitX(), int edges = kEdges) {
  return testing::acceptance_rod(magnetisation, edges);
}

RodField uniform(const Vec3& b) {
  return [b](const Vec3&) {
    magnetics::FieldSample s;
    s.b = b;
    return s;
  };
}

TEST(Rod, GradientMatchesFiniteDifferencesOfTheEnergy) {
  // A bent, twisted, stretched state in a dipole field with gravity and a tip force: every term of the energy.
  RodModel m = acceptance_rod(Vec3(0.3, 1.0, 0.2), 8);
  m.gravity = Vec3(0.5, -9.81, 1.0);
  m.tip_force = Vec3(1e-3, 2e-3, -1e-3);
  m.tip_moment = Vec3(2e-5, -1e-5, 3e-5);
  magnetics::FieldModel magnets;
  magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 50.0)},
              magnetics::Pose::from_axis(Vec3(0.03, -0.1, 0.02), Vec3(0.2, 1.0, 0.1)));
  const RodField field = field_function(magnets, magnets.rest_poses);
  RodState s = straight_rod(m);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Mat3& r : s.frames)
    r = Eigen::AngleAxisd(0.5 * u(rng), Vec3(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix() * r;
  testing::nodes_along_frames(m, s, 1e-6, rng);
  testing::expect_gradient_matches_energy(m, field, s, "rod");
  ASSERT_TRUE(static_cast<bool>(field.curvature()));  // a dipole's curvature is closed-form
  testing::expect_hessian_matches_finite_differences(m, field, s, "rod");
  // The same field without its curvature: the Hessian differences the field gradient instead.
  const RodField plain = [&field](const Vec3& x) { return field(x); };
  ASSERT_FALSE(static_cast<bool>(plain.curvature()));
  testing::expect_hessian_matches_finite_differences(m, plain, s, "rod, differenced curvature");
}

TEST(Rod, AnchorTermsMatchFiniteDifferences) {
  // Tangential anchors (a unit normal, a short one, none; the tool channel's held nodes), on a bent rod without
  // other loads.
  RodModel m = acceptance_rod(Vec3::UnitX(), 6);
  m.mass_per_length = 0.0;
  m.moment_per_length.clear();
  RodState s = straight_rod(m);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Mat3& r : s.frames) r = Eigen::AngleAxisd(0.2 * u(rng), Vec3(u(rng), u(rng), u(rng)).normalized()) * r;
  testing::nodes_along_frames(m, s, 1e-6, rng);
  RodConstraints c;
  c.anchors.push_back({3, s.x[3] + Vec3(0.4e-3, -0.2e-3, 0.1e-3), Vec3(0.0, 0.6, 0.8), 2e3});
  c.anchors.push_back({6, s.x[6] + Vec3(-0.2e-3, 0.3e-3, 0.0), Vec3::UnitZ(), 2e3});
  // An anchor whose normal is shorter than 1, or zero: it also holds the node partly across the wall.
  c.anchors.push_back({2, s.x[2] + Vec3(0.3e-3, 0.2e-3, -0.4e-3), Vec3(0.0, 0.3, 0.4), 2e3});
  c.anchors.push_back({4, s.x[4] + Vec3(-0.1e-3, 0.2e-3, 0.3e-3), Vec3::Zero(), 2e3});
  testing::expect_gradient_matches_energy(m, {}, s, "constraints", &c);
  testing::expect_hessian_matches_finite_differences(m, {}, s, "constraints", &c);
}

TEST(Rod, RestStrainTermsMatchFiniteDifferences) {
  // RodModel::rest_strain shifts each joint's law: the same derivative checks with a random rest strain per joint
  // (up to 20 /m of bend and twist, joints of 1.2 mm: up to 1.4° of rest turn each), rod and vine laws.
  RodModel m = acceptance_rod(Vec3(0.3, 1.0, 0.2), 8);
  m.gravity = Vec3(0.5, -9.81, 1.0);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int j = 0; j < m.edges; ++j) m.rest_strain.push_back(20.0 * Vec3(u(rng), u(rng), u(rng)));
  RodState s = straight_rod(m);
  for (Mat3& r : s.frames)
    r = Eigen::AngleAxisd(0.3 * u(rng), Vec3(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix() * r;
  testing::nodes_along_frames(m, s, 1e-6, rng);
  testing::expect_gradient_matches_energy(m, {}, s, "rest strain");
  testing::expect_hessian_matches_finite_differences(m, {}, s, "rest strain");
}

TEST(Rod, AnUnloadedRodWithUniformRestCurvatureIsACircularArc) {
  // Independent reference: with no loads a rod of uniform rest curvature κ0 (about d3) relaxes to the arc of
  // curvature κ0, tip at (sin κ0L/κ0, (1 − cos κ0L)/κ0). The discrete arc's joints turn by ψ with 2 tan(ψ/2)/ℓ =
  // κ0, so its tip differs from the continuum by O(h²): 1e-4 L at 100 edges (κ0L = 2 rad, h = 0.6 mm gives
  // (κ0h)²/12 ≈ 4e-5 per unit of turning).
  RodModel m = acceptance_rod(Vec3::UnitX(), 100);
  m.mass_per_length = 0.0;
  m.moment_per_length.clear();
  const double kappa = 2.0 / kLength;
  m.rest_strain.assign(static_cast<std::size_t>(m.edges), Vec3(0.0, 0.0, kappa));
  RodState s = straight_rod(m);
  const RodSolveReport r = solve_rod_statics(m, {}, s);
  ASSERT_TRUE(r.converged) << r.failure;
  const Vec3 expected(std::sin(kappa * kLength) / kappa, (1.0 - std::cos(kappa * kLength)) / kappa, 0.0);
  std::printf("  tip (%.4f, %.4f) mm vs the arc (%.4f, %.4f) mm\n", 1e3 * s.tip().x(), 1e3 * s.tip().y(),
              1e3 * expected.x(), 1e3 * expected.y());
  EXPECT_LT((s.tip() - expected).norm(), 1e-4 * kLength);
  // The bending moments vanish at rest.
  for (const double moment : joint_bending_moments(m, s)) EXPECT_LT(moment, 1e-9);
}

TEST(Rod, TipMomentGradientMatchesFiniteDifferences) {
  // The tip moment's term alone (the difference of two models that differ only in it), at a last edge turned by
  // 0.3–1.2 rad from the clamp, where J_l⁻¹(φ) differs from I by up to ~40 %. Tolerance 1e-5 of |M|: the round-off
  // of the two full energies (dominated by the stretched last edge) over the 1e-6 step is ~1e-6 of |M|.
  RodModel without = acceptance_rod(Vec3::UnitX(), 4);
  RodModel with = without;
  with.tip_moment = Vec3(2e-5, -1e-5, 3e-5);
  RodState s = straight_rod(without);
  for (const double angle : {0.3, 0.7, 1.2}) {
    s.frames.back() = Eigen::AngleAxisd(angle, Vec3(0.3, 1.0, -0.5).normalized()).toRotationMatrix();
    const VecX g = rod_gradient(with, {}, s) - rod_gradient(without, {}, s);
    for (int axis = 0; axis < 3; ++axis) {
      const auto energy = [&](double d) {
        RodState t = s;
        t.frames.back() = Eigen::AngleAxisd(d, Vec3::Unit(axis)).toRotationMatrix() * t.frames.back();
        return rod_energy(with, {}, t) - rod_energy(without, {}, t);
      };
      const double fd = (energy(1e-6) - energy(-1e-6)) / 2e-6;
      EXPECT_NEAR(g[g.size() - 3 + axis], fd, 1e-5 * with.tip_moment.norm()) << angle << " axis " << axis;
    }
  }
}

TEST(Rod, SmallLoadsMatchEulerBernoulliWithinHalfAPercent) {
  // Tip force FL³/3EI, uniform load qL⁴/8EI, tip moment ML²/2EI.
  // Acceptance: within 0.5 %. δ/L ≈ 1e-3 keeps the geometric nonlinearity below 1e-6.
  const RodModel base = acceptance_rod();
  const double ei = base.bending_stiffness_3;
  {
    RodModel m = base;
    m.mass_per_length = 0.0;
    const double force = 1e-3 * 3.0 * ei / (kLength * kLength);
    m.tip_force = Vec3(0.0, force, 0.0);
    RodState s = straight_rod(m);
    ASSERT_TRUE(solve_rod_statics(m, {}, s).converged);
    const double expected = force * std::pow(kLength, 3) / (3.0 * ei);
    EXPECT_NEAR(s.tip().y(), expected, 5e-3 * expected);
  }
  {
    RodModel m = base;
    const double q = 1e-3 * 8.0 * ei / std::pow(kLength, 3);
    m.gravity = Vec3(0.0, -q / m.mass_per_length, 0.0);
    RodState s = straight_rod(m);
    ASSERT_TRUE(solve_rod_statics(m, {}, s).converged);
    const double expected = -q * std::pow(kLength, 4) / (8.0 * ei);
    EXPECT_NEAR(s.tip().y(), expected, 5e-3 * std::abs(expected));
  }
  {
    RodModel m = base;
    m.mass_per_length = 0.0;
    const double moment = 1e-3 * 2.0 * ei / kLength;  // δ = ML²/2EI = 1e-3 L
    m.tip_moment = Vec3(0.0, 0.0, moment);             // about d3: bends towards +y
    RodState s = straight_rod(m);
    ASSERT_TRUE(solve_rod_statics(m, {}, s).converged);
    const double expected = moment * kLength * kLength / (2.0 * ei);
    EXPECT_NEAR(s.tip().y(), expected, 5e-3 * expected);
  }
}

TEST(Rod, CircularSectionMatchesEulerBernoulli) {
  // Ø2 mm, 60 mm, G 120 kPa: EI = 3G·πd⁴/64; tip force for δ/L = 1e-3, FL³/3EI within 0.5 %.
  RodModel m = circular_rod(kLength, 2e-3, kG, kRho, kEdges);
  const double ei = 3.0 * kG * kPi * std::pow(2e-3, 4) / 64.0;
  EXPECT_NEAR(m.bending_stiffness_2, ei, 1e-12 * ei);
  const double force = 1e-3 * 3.0 * ei / (kLength * kLength);
  m.tip_force = Vec3(0.0, 0.0, force);  // along the binormal: bending about d2
  RodState s = straight_rod(m);
  ASSERT_TRUE(solve_rod_statics(m, {}, s).converged);
  const double expected = force * std::pow(kLength, 3) / (3.0 * ei);
  EXPECT_NEAR(s.tip().z(), expected, 5e-3 * expected);
}

/// The elastica reference of the same beam (Euler–Bernoulli: no stretch or shear).
ElasticaProblem reference_of(const RodModel& m, PlanarMagnetisation magnetisation, const RodField& field) {
  ElasticaProblem p;
  p.length = m.length;
  p.bending_stiffness = m.bending_stiffness_3;
  p.area = kSide * kSide;
  p.density = kRho;
  p.gravity = m.gravity.head<2>();
  p.remanence = kBr;
  p.magnetisation = magnetisation;
  p.field = field;
  return p;
}

struct LargeCase {
  const char* name;
  PlanarMagnetisation magnetisation;
  RodField field;
};

TEST(Rod, LargeDeflectionsMatchTheElasticaWithinOnePercentOfTheLength) {
  // Acceptance: clamped horizontally, gravity on; uniform fields 1–20 mT perpendicular and at 135°; normal
  // magnetisation; the Ø101.6 mm N52 EPM as a dipole 150–250 mm away. Tip position error < 1 % of L at the default
  // resolution (50 edges).
  std::vector<LargeCase> cases;
  for (const double mt : {1.0, 5.0, 10.0, 20.0}) {
    for (const double deg : {90.0, 135.0}) {
      const double b = mt * kMtToT;
      cases.push_back({"uniform", PlanarMagnetisation::kAxial,
                       uniform(b * Vec3(std::cos(deg * kDegToRad), std::sin(deg * kDegToRad), 0.0))});
    }
  }
  cases.push_back({"uniform, normal magnetisation", PlanarMagnetisation::kNormal, uniform(Vec3(10e-3, 0.0, 0.0))});
  const double radius = 50.8e-3;
  const double epm = 1.45 * kPi * radius * radius * 2.0 * radius / kMu0;  // N52, m = Br·V/μ0
  for (const double distance : {0.15, 0.2, 0.25}) {
    magnetics::FieldModel magnets;
    // Below the beam's midpoint, moment along +y (orthogonal to the axial magnetisation: torque-dominated).
    magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, epm)},
                magnetics::Pose::from_axis(Vec3(0.5 * kLength, -distance, 0.0), Vec3::UnitY()));
    cases.push_back({"dipole", PlanarMagnetisation::kAxial, field_function(magnets, magnets.rest_poses)});
  }
  for (const LargeCase& c : cases) {
    const Vec3 direction = c.magnetisation == PlanarMagnetisation::kAxial ? Vec3::UnitX() : Vec3::UnitY();
    RodModel m = acceptance_rod(direction);
    m.gravity = Vec3(0.0, -9.81, 0.0);
    RodState s = straight_rod(m);
    const RodSolveReport report = solve_rod_statics(m, c.field, s);
    ASSERT_TRUE(report.converged) << c.name << ": " << report.failure;
    const ElasticaSolution ref = solve_elastica(reference_of(m, c.magnetisation, c.field));
    ASSERT_TRUE(ref.converged) << c.name;
    const double error = (s.tip().head<2>() - ref.tip()).norm() / kLength;
    EXPECT_LT(error, 0.01) << c.name << " tip " << s.tip().transpose() << " reference " << ref.tip().transpose();
    EXPECT_NEAR(s.tip().z(), 0.0, 1e-9) << c.name;  // stays in its plane
    std::printf("  %-32s tip (%7.2f, %7.2f) mm, reference (%7.2f, %7.2f) mm, error %.3f %% of L, %d iterations\n",
                c.name, 1e3 * s.tip().x(), 1e3 * s.tip().y(), 1e3 * ref.tip().x(), 1e3 * ref.tip().y(), 100 * error,
                report.iterations);
  }
}

TEST(Rod, TipErrorFallsWithResolutionAtSecondOrder) {
  // Gravity and 10 mT perpendicular, against the elastica (RK4, 4000 steps: its own error ~1e-12 L). The discrete
  // strains are centred differences, so the error should fall as h²; asserted ≥ 1.7 over each halving.
  RodModel m = acceptance_rod();
  m.gravity = Vec3(0.0, -9.81, 0.0);
  const RodField field = uniform(Vec3(0.0, 10e-3, 0.0));
  const ElasticaSolution ref = solve_elastica(reference_of(m, PlanarMagnetisation::kAxial, field), {.intervals = 4000});
  ASSERT_TRUE(ref.converged);
  std::vector<double> errors;
  for (const int edges : {10, 20, 40, 80}) {
    RodModel r = acceptance_rod(Vec3::UnitX(), edges);
    r.gravity = m.gravity;
    RodState s = straight_rod(r);
    ASSERT_TRUE(solve_rod_statics(r, field, s).converged) << edges;
    errors.push_back((s.tip().head<2>() - ref.tip()).norm() / kLength);
  }
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double order = std::log2(errors[i - 1] / errors[i]);
    std::printf("  edges %3d: tip error %.3e L, order %.2f\n", 10 << i, errors[i], order);
    EXPECT_GT(order, 1.7) << "halving " << i;
  }
}

TEST(Rod, PhysicalStretchAndShearMoveTheTipByAboutOnePercentUnderTheEpm) {
  // The claim behind kNearInextensible: the physical EA and κGA of the silicone beam (factor 1) under the thesis
  // EPM at 150 mm give a tip 1–3 % of L away from the inextensible elastica; the default factor stays within 0.4 %.
  const double radius = 50.8e-3;
  magnetics::FieldModel magnets;
  magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 1.45 * kPi * radius * radius * 2.0 * radius / kMu0)},
              magnetics::Pose::from_axis(Vec3(0.5 * kLength, -0.15, 0.0), Vec3::UnitY()));
  const RodField field = field_function(magnets, magnets.rest_poses);
  const auto tip_error = [&](double factor) {
    RodModel m = testing::acceptance_rod(Vec3::UnitX(), kEdges, factor);
    m.gravity = Vec3(0.0, -9.81, 0.0);
    RodState s = straight_rod(m);
    EXPECT_TRUE(solve_rod_statics(m, field, s).converged);
    const ElasticaSolution ref = solve_elastica(reference_of(m, PlanarMagnetisation::kAxial, field));
    return (s.tip().head<2>() - ref.tip()).norm() / kLength;
  };
  const double physical = tip_error(1.0);
  EXPECT_GT(physical, 0.01);
  EXPECT_LT(physical, 0.03);
  EXPECT_LT(tip_error(kNearInextensible), 0.004);
}

TEST(Rod, WorkspaceReusesTheHessianAndReachesTheSameEquilibria) {
  // A simulation-like sequence: the EPM (dipole, 150 mm below) steps 2 mm at a time along the beam; each solve
  // starts from the previous equilibrium. With a workspace (chord steps on the previous Hessian) the equilibria
  // must be those of plain Newton (both stop at the same gradient tolerance: ~1e-9 L apart; asserted 1e-7 L) with
  // fewer Hessians than iterations.
  const double radius = 50.8e-3;
  RodModel m = acceptance_rod();
  m.gravity = Vec3(0.0, -9.81, 0.0);
  RodState plain = straight_rod(m);
  RodState reused = plain;
  RodWorkspace workspace;
  int iterations = 0;
  int hessians = 0;
  for (int k = 0; k < 8; ++k) {
    magnetics::FieldModel magnets;
    magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 1.45 * kPi * radius * radius * 2.0 * radius / kMu0)},
                magnetics::Pose::from_axis(Vec3(0.02 + 2e-3 * k, -0.15, 0.0), Vec3::UnitY()));
    const RodField field = field_function(magnets, magnets.rest_poses);
    ASSERT_TRUE(solve_rod_statics(m, field, plain).converged) << k;
    const RodSolveReport r = solve_rod_statics(m, field, reused, {}, &workspace);
    ASSERT_TRUE(r.converged) << k << ": " << r.failure;
    EXPECT_LT((plain.tip() - reused.tip()).norm(), 1e-7 * kLength) << k;
    if (k > 0) {
      iterations += r.iterations;
      hessians += r.hessians;
    }
  }
  std::printf("  warm solves with a workspace: %d iterations, %d Hessians\n", iterations, hessians);
  EXPECT_LT(hessians, iterations);
}

TEST(Rod, BadModelsAreRejected) {
  RodModel m = acceptance_rod();
  m.length = 0.0;
  RodState s;
  EXPECT_THROW(solve_rod_statics(m, {}, s), InputError);
  m = acceptance_rod();
  m.bending_stiffness_3 = -1.0;
  EXPECT_THROW(solve_rod_statics(m, {}, s), InputError);
  m = acceptance_rod();
  s = straight_rod(m);
  s.x.pop_back();
  EXPECT_THROW(solve_rod_statics(m, {}, s), InputError);
  m = acceptance_rod();
  s = straight_rod(m);
  m.rest_strain.assign(3, Vec3::Zero());  // not one per edge
  EXPECT_THROW(solve_rod_statics(m, {}, s), InputError);
}

}  // namespace
}  // namespace magvine::robot
