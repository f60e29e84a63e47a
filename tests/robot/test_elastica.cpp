// The planar elastica reference solver (robot/elastica.hpp) against independent references:
//  * Euler–Bernoulli closed forms at small loads (tip force, uniform load from gravity, tip moment, distributed
//    torque and gradient force);
//  * first integrals of the large-deflection elastica evaluated by quadrature, independent of the shooting code:
//    tip force (Bisshopp & Drucker 1945) and a uniform field acting on axial magnetisation (Wang et al. 2020);
//  * the buckling load β = π²/4 of a beam in an antiparallel field (PHYSICS.md §7);
//  * the order of the RK4 integration.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/robot/elastica.hpp"

namespace magvine::robot {
namespace {

// The beam of the acceptance tests (60 × 3 × 3 mm, G = 120 kPa, E = 3G, NdFeB–Dragon Skin).
constexpr double kLength = 60e-3;
constexpr double kSide = 3e-3;
constexpr double kE = 3.0 * 120e3;
constexpr double kI = kSide * kSide * kSide * kSide / 12.0;
constexpr double kEI = kE * kI;
constexpr double kArea = kSide * kSide;

ElasticaProblem beam() {
  ElasticaProblem p;
  p.length = kLength;
  p.bending_stiffness = kEI;
  p.area = kArea;
  p.density = 1882.0;
  return p;
}

/// Composite Simpson's rule of f on [a, b] with n (even) intervals.
double simpson(const std::function<double(double)>& f, double a, double b, int n = 20000) {
  const double h = (b - a) / n;
  double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += (i % 2 == 1 ? 4.0 : 2.0) * f(a + i * h);
  return sum * h / 3.0;
}

/// Root of the increasing function g on [lo, hi] by bisection.
double bisect(const std::function<double(double)>& g, double lo, double hi) {
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (g(mid) < 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// ---- Small loads: Euler–Bernoulli. At δ/L ≈ 1e-4 the geometric nonlinearity is O((δ/L)²) = 1e-8 relative and the
// RK4 error (1000 steps) below 1e-12, so 1e-6 relative is a safe bound that still catches any factor or sign error.
constexpr double kSmallTol = 1e-6;

TEST(Elastica, SmallTipForceMatchesEulerBernoulli) {
  ElasticaProblem p = beam();
  const double force = 1e-4 * 3.0 * kEI / (kLength * kLength);  // δ/L = 1e-4
  p.tip_force = {0.0, force};
  const ElasticaSolution s = solve_elastica(p);
  ASSERT_TRUE(s.converged);
  const double expected = force * std::pow(kLength, 3) / (3.0 * kEI);
  EXPECT_NEAR(s.tip().y(), expected, kSmallTol * expected);
  EXPECT_NEAR(s.base_force.y(), force, 1e-9 * force);  // statics: the clamp carries the load
  EXPECT_NEAR(s.base_moment, force * kLength, 1e-6 * force * kLength);
}

TEST(Elastica, SmallGravityLoadMatchesEulerBernoulli) {
  ElasticaProblem p = beam();
  const double q_target = 1e-4 * 8.0 * kEI / std::pow(kLength, 3);  // δ/L = 1e-4
  p.gravity = {0.0, -q_target / (p.density * p.area)};
  const ElasticaSolution s = solve_elastica(p);
  ASSERT_TRUE(s.converged);
  const double expected = -q_target * std::pow(kLength, 4) / (8.0 * kEI);
  EXPECT_NEAR(s.tip().y(), expected, kSmallTol * std::abs(expected));
}

TEST(Elastica, SmallTipMomentMatchesEulerBernoulli) {
  ElasticaProblem p = beam();
  const double moment = 1e-4 * 2.0 * kEI / kLength;
  p.tip_moment = moment;
  const ElasticaSolution s = solve_elastica(p);
  ASSERT_TRUE(s.converged);
  const double expected = moment * kLength * kLength / (2.0 * kEI);
  EXPECT_NEAR(s.tip().y(), expected, kSmallTol * expected);
  // A pure moment bends a circle: exact tip angle ML/EI at any size.
  EXPECT_NEAR(s.tip_angle(), moment * kLength / kEI, 1e-12);
}

TEST(Elastica, SmallMagneticTorqueAndGradientForceMatchEulerBernoulli) {
  // Axial magnetisation M = Br/μ0 along x at small deflection.
  const double br = 0.125;
  const double m = br / kMu0;
  // (a) B = (0, g·x): torque per length τ = A·M·g·x, no force (G_yx only) → δ = 5·A·M·g·L⁴/(24 EI).
  {
    ElasticaProblem p = beam();
    p.remanence = br;
    const double g = 1e-4 * 24.0 * kEI / (5.0 * kArea * m * std::pow(kLength, 3));
    p.field = [g](const Vec3& x) {
      magnetics::FieldSample f;
      f.b = Vec3(0.0, g * x.x(), 0.0);
      f.g(1, 0) = g;
      return f;
    };
    const ElasticaSolution s = solve_elastica(p);
    ASSERT_TRUE(s.converged);
    const double expected = 5.0 * kArea * m * g * std::pow(kLength, 4) / (24.0 * kEI);
    EXPECT_NEAR(s.tip().y(), expected, 1e-5 * expected);  // τ also picks up B_x = 0 but rotates with θ: O(δ/L)
  }
  // (b) B = (g·y, 0): on the axis B ≈ 0, force per length f_y = A·M·G_xy = A·M·g → δ = qL⁴/8EI.
  {
    ElasticaProblem p = beam();
    p.remanence = br;
    const double g = 1e-4 * 8.0 * kEI / (kArea * m * std::pow(kLength, 3));
    p.field = [g](const Vec3& x) {
      magnetics::FieldSample f;
      f.b = Vec3(g * x.y(), 0.0, 0.0);
      f.g(0, 1) = g;
      return f;
    };
    const ElasticaSolution s = solve_elastica(p);
    ASSERT_TRUE(s.converged);
    const double expected = kArea * m * g * std::pow(kLength, 4) / (8.0 * kEI);
    EXPECT_NEAR(s.tip().y(), expected, 1e-5 * expected);  // B_x = g·y adds a torque O(δ/L) relative
  }
}

// ---- Large deflection under a tip force P (downward): θ'² = (2P/EI)(sin θ − sin θ_L). With sin θ = sin θ_L + v²
// the length and tip coordinates are smooth integrals in v ∈ [0, √sin α], α = −θ_L:
//   L = √(2EI/P) ∫ dv / cos θ,  y_L = √(2EI/P) ∫ sin θ / cos θ dv,  x_L = √(2EI/P)·√(sin α).
struct TipLoadReference {
  double angle;  // α = −θ_L
  double x;
  double y;
};

TipLoadReference tip_load_reference(double load /* PL²/EI */) {
  const double k = std::sqrt(2.0 / load);  // √(2EI/P) in units of L
  const auto length = [&](double alpha) {
    const double sa = std::sin(alpha);
    return k * simpson([sa](double v) { return 1.0 / std::sqrt(1.0 - std::pow(v * v - sa, 2)); }, 0.0, std::sqrt(sa));
  };
  const double alpha = bisect([&](double a) { return length(a) - 1.0; }, 1e-9, 0.5 * kPi - 1e-9);
  const double sa = std::sin(alpha);
  const double y = k * simpson([sa](double v) { return (v * v - sa) / std::sqrt(1.0 - std::pow(v * v - sa, 2)); }, 0.0,
                               std::sqrt(sa));
  return {alpha, k * std::sqrt(sa), y};
}

TEST(Elastica, LargeTipForceMatchesTheQuadratureOfItsFirstIntegral) {
  // RK4 with 1000 steps: ~1e-12 L; the quadrature (Simpson, 20 000 intervals of a smooth integrand): ~1e-14.
  constexpr double kTol = 1e-9;
  for (const double load : {1.0, 3.0, 10.0}) {
    ElasticaProblem p = beam();
    p.tip_force = {0.0, -load * kEI / (kLength * kLength)};
    const ElasticaSolution s = solve_elastica(p);
    ASSERT_TRUE(s.converged) << load;
    const TipLoadReference ref = tip_load_reference(load);
    EXPECT_NEAR(s.tip_angle(), -ref.angle, kTol) << "PL²/EI = " << load;
    EXPECT_NEAR(s.tip().x() / kLength, ref.x, kTol) << "PL²/EI = " << load;
    EXPECT_NEAR(s.tip().y() / kLength, ref.y, kTol) << "PL²/EI = " << load;
    if (load == 1.0) {
      // Bisshopp & Drucker (1945), table: PL²/EI = 1 → vertical deflection 0.3017 L, horizontal 0.0564 L.
      EXPECT_NEAR(-s.tip().y() / kLength, 0.3017, 1e-4);
      EXPECT_NEAR(1.0 - s.tip().x() / kLength, 0.0564, 1e-4);
    }
  }
}

// ---- Uniform field B at angle φ on axial magnetisation: θ'' = −c·sin(φ − θ), c = A·Br·|B|/(μ0 EI), θ'(L) = 0, so
// θ'² = 2c[cos(φ − θ_L) − cos(φ − θ)] = 4c·sin(φ − θ_L + v²/2)·sin(v²/2) with θ = θ_L − v²; then
//   L = ∫ 2v dv / θ'(v),  v ∈ [0, √θ_L]   (integrand → 2/√(2c·sin(φ − θ_L)) as v → 0).
double field_tip_angle_reference(double beta /* cL² */, double phi) {
  const auto length = [&](double theta_l) {
    const double a = phi - theta_l;
    return simpson(
        [&](double v) {
          if (v == 0.0) return 2.0 / std::sqrt(2.0 * beta * std::sin(a));
          return 2.0 * v / std::sqrt(4.0 * beta * std::sin(a + 0.5 * v * v) * std::sin(0.5 * v * v));
        },
        0.0, std::sqrt(theta_l));
  };
  return bisect([&](double t) { return length(t) - 1.0; }, 1e-12, phi - 1e-9);
}

ElasticaProblem field_problem(double beta, double phi, PlanarMagnetisation magnetisation) {
  ElasticaProblem p = beam();
  p.remanence = 0.125;
  p.magnetisation = magnetisation;
  const double b = beta * kEI * kMu0 / (kArea * p.remanence * kLength * kLength);
  const Vec3 field(b * std::cos(phi), b * std::sin(phi), 0.0);
  p.field = [field](const Vec3&) {
    magnetics::FieldSample f;
    f.b = field;
    return f;
  };
  return p;
}

TEST(Elastica, UniformFieldOnAxialMagnetisationMatchesTheQuadratureOfItsFirstIntegral) {
  constexpr double kTol = 1e-9;  // rad; as above
  for (const double beta : {1.0, 5.0, 20.0}) {
    for (const double phi_deg : {90.0, 135.0}) {
      const double phi = phi_deg * kDegToRad;
      const ElasticaSolution s = solve_elastica(field_problem(beta, phi, PlanarMagnetisation::kAxial));
      ASSERT_TRUE(s.converged);
      EXPECT_NEAR(s.tip_angle(), field_tip_angle_reference(beta, phi), kTol) << "β " << beta << " φ " << phi_deg;
    }
  }
}

TEST(Elastica, NormalMagnetisationIsAxialInAFieldTurnedBack90Degrees) {
  // d_normal = ẑ × t, so (d_normal × B)_z = |B| sin(φ − π/2 − θ).
  const ElasticaSolution normal = solve_elastica(field_problem(4.0, 0.0, PlanarMagnetisation::kNormal));
  const ElasticaSolution axial = solve_elastica(field_problem(4.0, -0.5 * kPi, PlanarMagnetisation::kAxial));
  ASSERT_TRUE(normal.converged && axial.converged);
  EXPECT_LT(normal.tip_angle(), -0.3);  // a field along +x turns a +y-magnetised beam clockwise
  EXPECT_NEAR(normal.tip_angle(), axial.tip_angle(), 1e-10);
  EXPECT_NEAR((normal.tip() - axial.tip()).norm(), 0.0, 1e-12);
}

TEST(Elastica, AntiparallelFieldBucklesAtPiSquaredOverFour) {
  // A 0.01 rad imperfection of the field direction selects the branch; below β = π²/4 the tip barely turns (the
  // linear amplification ε/(1 − β/β_c) gives ≤ 0.05 rad), above it the beam flips over.
  const double critical = kPi * kPi / 4.0;
  const double phi = kPi - 0.01;
  const ElasticaSolution below = solve_elastica(field_problem(0.8 * critical, phi, PlanarMagnetisation::kAxial));
  const ElasticaSolution above = solve_elastica(field_problem(1.2 * critical, phi, PlanarMagnetisation::kAxial));
  ASSERT_TRUE(below.converged && above.converged);
  EXPECT_LT(below.tip_angle(), 0.06);
  EXPECT_GT(above.tip_angle(), 1.0);
  EXPECT_NEAR(above.tip_angle(), field_tip_angle_reference(1.2 * critical, phi), 1e-8);
}

TEST(Elastica, RotatingTheClampAndTheLoadsRotatesTheSolution) {
  // Tip force with both components and gravity, then the same problem turned by 30° (clamp, force, gravity): the
  // shape turns with it. Catches a sign or component error in the n_x terms, which loads along y alone never use.
  ElasticaProblem p = beam();
  p.tip_force = Eigen::Vector2d(0.4, -1.5) * kEI / (kLength * kLength);
  p.gravity = {0.0, -9.81};
  const ElasticaSolution a = solve_elastica(p);
  const double turn = 30.0 * kDegToRad;
  const Eigen::Rotation2Dd r(turn);
  p.base_angle = turn;
  p.tip_force = r * p.tip_force;
  p.gravity = r * p.gravity;
  const ElasticaSolution b = solve_elastica(p);
  ASSERT_TRUE(a.converged && b.converged);
  EXPECT_NEAR((r * a.tip() - b.tip()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(b.tip_angle() - a.tip_angle(), turn, 1e-12);
}

TEST(Elastica, AxialCompressionBucklesAtTheEulerLoad) {
  // Cantilever under a compressive tip force along −x: P_cr = π²EI/(4L²). A 1 % transverse imperfection selects
  // the branch; below P_cr the tip turns little (≈ 0.01/(1 − P/P_cr) rad scale), above it the beam bends over.
  const double critical = kPi * kPi * kEI / (4.0 * kLength * kLength);
  ElasticaProblem p = beam();
  p.tip_force = Eigen::Vector2d(-0.8 * critical, -0.01 * critical);
  const ElasticaSolution below = solve_elastica(p);
  p.tip_force = Eigen::Vector2d(-1.5 * critical, -0.01 * critical);
  const ElasticaSolution above = solve_elastica(p);
  ASSERT_TRUE(below.converged && above.converged);
  EXPECT_GT(below.tip_angle(), -0.15);
  EXPECT_LT(above.tip_angle(), -1.0);
}

TEST(Elastica, Rk4ConvergesAtFourthOrder) {
  ElasticaProblem p = beam();
  p.tip_force = {0.0, -3.0 * kEI / (kLength * kLength)};
  const double exact = -tip_load_reference(3.0).angle;
  const auto error = [&](int n) { return std::abs(solve_elastica(p, {.intervals = n}).tip_angle() - exact); };
  const double e1 = error(10);
  const double e2 = error(20);
  const double order = std::log2(e1 / e2);
  EXPECT_GT(order, 3.7) << "errors " << e1 << ", " << e2;
  EXPECT_LT(order, 4.3);
}

TEST(Elastica, WeakDipoleFieldMatchesEulerBernoulliWithItsTorqueAndGradientForce) {
  // The thesis EPM as a dipole (N52, Ø101.6 × 101.6 mm, Br 1.45 T: m = Br·V/μ0), 150 mm below and 50 mm beyond
  // the tip, moment along +x, scaled down 1e-5 so the beam (axial magnetisation) stays in the linear range. On the
  // straight beam the loads per length are τ(u) = A·M·B_y and f_y(u) = A·M·∂B_x/∂y (f_j = Σ_i M_i ∂B_i/∂x_j), and
  // Euler–Bernoulli gives the tip deflection by one quadrature:
  //   y(L) = (1/EI) ∫_0^L [τ(u)(Lu − u²/2) + f_y(u)(Lu²/2 − u³/6)] du.
  // Tolerance 1e-3 relative: the shooting samples the field on the deflected beam (δ/L ~ 1e-4, field scale 150 mm).
  const double radius = 50.8e-3;
  const double moment = 1e-5 * 1.45 * kPi * radius * radius * 2.0 * radius / kMu0;
  magnetics::FieldModel model;
  model.add(magnetics::DipoleSource{Vec3(0.0, 0.0, moment)},
            magnetics::Pose::from_axis(Vec3(kLength + 0.05, -0.15, 0.0), Vec3::UnitX()));
  ElasticaProblem p = beam();
  p.remanence = 0.125;
  p.field = field_function(model, model.rest_poses);
  const ElasticaSolution s = solve_elastica(p);
  ASSERT_TRUE(s.converged);
  const double m = p.remanence / kMu0;
  const double expected =
      simpson(
          [&](double u) {
            const magnetics::FieldSample f = magnetics::field_gradient(model, model.rest_poses, Vec3(u, 0.0, 0.0));
            const double tau = kArea * m * f.b.y();
            const double force = kArea * m * f.g(0, 1);
            return tau * (kLength * u - 0.5 * u * u) + force * (0.5 * kLength * u * u - u * u * u / 6.0);
          },
          0.0, kLength, 2000) /
      kEI;
  ASSERT_GT(std::abs(expected), 1e-5 * kLength);  // the loads do bend it
  EXPECT_NEAR(s.tip().y(), expected, 1e-3 * std::abs(expected));
  // Both terms matter here: dropping the gradient force moves the answer by more than the tolerance.
  const double torque_only = simpson(
                                 [&](double u) {
                                   const magnetics::FieldSample f =
                                       magnetics::field_gradient(model, model.rest_poses, Vec3(u, 0.0, 0.0));
                                   return kArea * m * f.b.y() * (kLength * u - 0.5 * u * u);
                                 },
                                 0.0, kLength, 2000) /
                             kEI;
  EXPECT_GT(std::abs(torque_only - expected), 1e-2 * std::abs(expected));
  // In a curl-free field ∂B_x/∂y = ∂B_y/∂x, so the integrand is A·M·d/du[B_y(u)(Lu²/2 − u³/6)] and the loads of an
  // axially magnetised straight beam act like the tip force A·M·B_y(L): y(L) = A·M·B_y(L)·L³/(3EI).
  const double b_tip = magnetics::field(model, model.rest_poses, Vec3(kLength, 0.0, 0.0)).y();
  EXPECT_NEAR(expected, kArea * m * b_tip * std::pow(kLength, 3) / (3.0 * kEI), 1e-9 * std::abs(expected));
}

TEST(Elastica, BadInputIsRejected) {
  ElasticaProblem p = beam();
  p.length = 0.0;
  EXPECT_THROW(solve_elastica(p), InputError);
  p = beam();
  p.bending_stiffness = -1.0;
  EXPECT_THROW(solve_elastica(p), InputError);
  p = beam();
  EXPECT_THROW(solve_elastica(p, {.intervals = 0}), InputError);
}

}  // namespace
}  // namespace magvine::robot
