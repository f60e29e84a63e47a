// Implicit dynamics of the rod (robot/rod.hpp: backward Euler as an incremental potential): the cantilever's first
// bending mode against Euler–Bernoulli, stability of stiff rods at steps far beyond the explicit limit, and the
// accuracy-controlled stepping against fine fixed steps.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "magvine/core/units.hpp"
#include "magvine/robot/rod.hpp"

namespace magvine::robot {
namespace {

RodModel beam(double shear_modulus, int edges) {
  RodModel m = rectangular_rod(0.06, 3e-3, 3e-3, shear_modulus, 1882.0, 0.0, Vec3::UnitX(), edges);
  return m;
}

/// Euler–Bernoulli first-mode angular frequency of a cantilever: (1.8751)² √(EI/(ρA L⁴)).
double first_mode(const RodModel& m) {
  return 1.87510407 * 1.87510407 * std::sqrt(m.bending_stiffness_3 / (m.mass_per_length * std::pow(m.length, 4)));
}

TEST(RodDynamics, CantileverVibratesAtItsFirstModeFrequency) {
  // Released from the static shape under a small tip load (δ ≈ 1e-3 L). Reference: Euler–Bernoulli's first mode.
  // Tolerance 1 %: the lumped-mass chain of 30 edges is ~0.2 % stiff in its first mode, backward Euler lengthens
  // the period by (ω dt)²/3 ≈ 1e-4 at 400 steps per period, rotary inertia shortens ω by ~(r_g/L)² ≈ 1e-3.
  RodModel m = beam(120e3, 30);
  const double omega = first_mode(m);
  m.tip_force = Vec3(0.0, 1e-3 * 3.0 * m.bending_stiffness_3 / (m.length * m.length), 0.0);
  RodState s = straight_rod(m);
  ASSERT_TRUE(solve_rod_statics(m, {}, s).converged);
  m.tip_force = Vec3::Zero();
  RodMotion v = rod_at_rest(m);
  const double period = 2.0 * kPi / omega;
  const double dt = period / 400.0;
  std::vector<double> crossings;  // downward zero crossings of the tip's y
  double previous = s.tip().y();
  for (int k = 1; k <= 1400 && crossings.size() < 4; ++k) {
    const RodSolveReport r = step_rod_dynamics(m, {}, s, v, dt);
    ASSERT_TRUE(r.converged) << "step " << k << ": " << r.failure;
    const double y = s.tip().y();
    if (previous > 0.0 && y <= 0.0) crossings.push_back((k - 1 + previous / (previous - y)) * dt);
    previous = y;
  }
  ASSERT_GE(crossings.size(), 3u);
  const double measured = (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  std::printf("  period %.5f s, Euler–Bernoulli %.5f s (%.3f %%)\n", measured, period,
              100.0 * (measured / period - 1.0));
  EXPECT_NEAR(measured, period, 0.01 * period);
}

TEST(RodDynamics, StiffRodIsStableAtStepsFarBeyondTheExplicitLimit) {
  // G = 10 MPa: the highest mode of a 50-edge chain has ω ~ 1e6 rad/s, so an explicit step would need ~1e-6 s;
  // backward Euler at 10 ms (ω dt ~ 1e4) must stay finite and settle on the static sag under gravity.
  RodModel m = beam(10e6, 50);
  m.gravity = Vec3(0.0, -9.81, 0.0);
  RodState s = straight_rod(m);
  RodMotion v = rod_at_rest(m);
  for (int k = 0; k < 200; ++k) {
    const RodSolveReport r = step_rod_dynamics(m, {}, s, v, 0.01);
    ASSERT_TRUE(r.converged) << "step " << k << ": " << r.failure;
    for (const Vec3& x : s.x) ASSERT_TRUE(x.allFinite());
  }
  RodState rest = straight_rod(m);
  ASSERT_TRUE(solve_rod_statics(m, {}, rest).converged);
  // Backward Euler damps the first mode (ω ≈ 110 rad/s) by 1/√(1 + (ω dt)²) ≈ 0.67 a step: settled after 2 s.
  EXPECT_LT((s.tip() - rest.tip()).norm(), 1e-6 * m.length);
}

TEST(RodDynamics, AccuracyControlledStepsMatchFineFixedSteps) {
  // A soft rod falling under gravity from straight for 50 ms: the controlled run (tolerance 1e-5 L per step) against
  // 2000 fixed steps of 25 µs (backward Euler's global error O(dt): ~1e-5 L). Tolerance 1e-3 L.
  RodModel m = beam(120e3, 20);
  m.gravity = Vec3(0.0, -9.81, 0.0);
  RodState a = straight_rod(m);
  RodMotion va = rod_at_rest(m);
  const RodDynamicsReport report =
      simulate_rod_dynamics(m, {}, a, va, 0.05, {.max_step = 5e-3, .min_step = 1e-9, .tolerance = 1e-5});
  ASSERT_TRUE(report.completed) << report.failure;
  RodState b = straight_rod(m);
  RodMotion vb = rod_at_rest(m);
  for (int k = 0; k < 2000; ++k) ASSERT_TRUE(step_rod_dynamics(m, {}, b, vb, 25e-6).converged);
  std::printf("  controlled: %d steps (%d rejected); tip (%.3f, %.3f) mm vs fixed (%.3f, %.3f) mm\n", report.steps,
              report.rejected, 1e3 * a.tip().x(), 1e3 * a.tip().y(), 1e3 * b.tip().x(), 1e3 * b.tip().y());
  EXPECT_LT((a.tip() - b.tip()).norm(), 1e-3 * m.length);
  EXPECT_GT(-b.tip().y(), 1e-3);  // it did fall
}

}  // namespace
}  // namespace magvine::robot
