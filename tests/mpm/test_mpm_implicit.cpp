// The implicit MPM step: its Hessian against finite differences, exact transfers, and a stiff magnetic catheter's
// settled shape at far fewer steps, and each integrator's rest held by the other.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <type_traits>

#include "magvine/mpm/cantilever.hpp"
#include "magvine/mpm/mpm.hpp"
#include "magvine/mpm/sampling.hpp"
#include "mpm_test_bodies.hpp"

namespace magvine::mpm {
namespace {

using test_bodies::across;
using test_bodies::small_block;
using test_bodies::stiff_catheter;

TEST(MpmImplicit, TheStressDifferentialIsTheDerivativeOfTheStress) {
  // Against a central difference of elastic_stress at h = 1e-6 (truncation ~1e-12 relative, round-off ~1e-10 of the
  // stress scale): agreement to 1e-6 of |dP| checks every term of the closed form (a missing term is O(1) off).
  const Material m{3e5, 6e6, 1000.0};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  auto check = [&](auto f, Plane plane) {
    using M = decltype(f);
    M df;
    for (int r = 0; r < M::RowsAtCompileTime; ++r)
      for (int c = 0; c < M::ColsAtCompileTime; ++c) df(r, c) = u(rng);
    constexpr int D = M::RowsAtCompileTime;
    const double h = 1e-6;
    const M numeric = (elastic_stress<D>(m, f + h * df, plane) - elastic_stress<D>(m, f - h * df, plane)) / (2.0 * h);
    const M closed = elastic_stress_differential<D>(m, f, df, plane);
    if (plane != Plane::kStress) {  // plane stress's differential is itself this difference: checked below
      EXPECT_LT((closed - numeric).norm(), 1e-6 * numeric.norm()) << "plane " << static_cast<int>(plane);
    }
    // Against the energy (independent of the stress code): dF : dP[dF] = d²ψ/dε² along F + ε dF, by a second
    // difference at ε = 1e-4 (truncation ~1e-8 relative, round-off ~1e-8): to 1e-5 relative.
    const double e = 1e-4;
    const double second =
        (strain_energy_density<D>(m, f + e * df, plane) - 2.0 * strain_energy_density<D>(m, f, plane) +
         strain_energy_density<D>(m, f - e * df, plane)) /
        (e * e);
    EXPECT_NEAR((closed.array() * df.array()).sum(), second, 1e-5 * std::abs(second))
        << "plane " << static_cast<int>(plane);
  };
  for (int trial = 0; trial < 20; ++trial) {
    MatD<3> f3 = MatD<3>::Identity();
    MatD<2> f2 = MatD<2>::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) f3(r, c) += u(rng);
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c) f2(r, c) += u(rng);
    if (f3.determinant() > 0.2) check(f3, Plane::kStrain);
    if (f2.determinant() > 0.2) {
      check(f2, Plane::kStrain);
      check(f2, Plane::kStress);
    }
  }
}

TEST(MpmImplicit, FreeFallIsExactIn2DAnd3D) {
  // No stress: the solve's answer is v* itself (F̂ = F = I), the explicit step's symplectic Euler: v_n = n g Δt,
  // x_n = x0 + g Δt² n(n+1)/2, to round-off, at 100 times the explicit step: the transfers, the target and the
  // update are the explicit step's.
  auto run = [](auto dim) {
    constexpr int D = decltype(dim)::value;
    const CantileverSpec s = small_block();
    Cantilever<D> c = make_cantilever<D>(s);
    c.model.clamps.clear();
    c.model.gravity = VecD<D>::Zero();
    c.model.gravity[1] = -9.81;
    const auto x0 = c.state.x;
    MpmWorkspace<D> ws;
    const double dt = 100.0 * c.model.stable_step(0.4);
    const int n = 20;
    ImplicitStats stats;
    for (int k = 0; k < n; ++k) {
      const StepStatus st = implicit_step<D>(c.model, AppliedField{}, c.state, ws, dt, {}, &stats);
      EXPECT_TRUE(st.ok) << st.cause;
    }
    double worst = 0.0;
    for (std::size_t p = 0; p < x0.size(); ++p) {
      const VecD<D> expect = x0[p] + c.model.gravity * dt * dt * n * (n + 1) / 2.0;
      worst = std::max(worst, (c.state.x[p] - expect).norm());
      worst = std::max(worst, (c.state.v[p] - c.model.gravity * dt * n).norm() * dt);
      worst = std::max(worst, (c.state.f[p] - MatD<D>::Identity()).norm() * s.length);
    }
    EXPECT_LT(worst, 1e-12) << D << "D";  // 1e-12 m: round-off of a Newton solve of Δt² K ≫ M, far below a cell
  };
  run(std::integral_constant<int, 2>{});
  run(std::integral_constant<int, 3>{});
}

TEST(MpmImplicit, AnIndefiniteHessianIsProjectedAndStillFactored) {
  // A block whose particles carry random deformations of ±0.15 (some compressed far enough that the Neo-Hookean's
  // tangent is indefinite): the step's first factorization fails, the tangents are projected, and the factored
  // projected Hessian drives Newton to convergence (projected Newton: the gradient stays exact).
  auto run = [](auto d) {
    constexpr int D = decltype(d)::value;
    Cantilever<D> c = make_cantilever<D>(small_block());
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.15, 0.15);
    for (auto& f : c.state.f)
      for (int k = 0; k < D * D; ++k) f.data()[k] += u(rng);
    MpmWorkspace<D> ws;
    ImplicitStats stats;
    const StepStatus st =
        implicit_step<D>(c.model, AppliedField{}, c.state, ws, 20.0 * c.model.stable_step(0.4), {}, &stats);
    EXPECT_TRUE(st.ok) << st.cause;
    EXPECT_EQ(stats.factorizations, 1) << D << "D";
    EXPECT_LT(stats.correction, 1e-6) << D << "D";
    std::printf("%dD: %d Newton iterations, %ld CG\n", D, stats.newton, stats.cg);
  };
  run(std::integral_constant<int, 2>{});
  run(std::integral_constant<int, 3>{});
}

TEST(MpmImplicit, AtTheExplicitStepItFollowsTheExplicitPath) {
  // Backward Euler and the explicit step differ by O(Δt) per step: at the explicit step, over 1000 steps of the stiff
  // catheter's swing (the tip rises 0.18 mm), the two tips stay within 0.5 % of that rise (measured: 0.0025 %).
  Cantilever<2> ex = make_cantilever<2>(stiff_catheter());
  Cantilever<2> im = ex;
  const VecD<2> start = mean_position<2>(ex.state, ex.tip);
  MpmWorkspace<2> ws_ex, ws_im;
  const double dt = ex.model.stable_step(0.4);
  for (int k = 0; k < 1000; ++k) {
    ASSERT_TRUE(step<2>(ex.model, across(), ex.state, ws_ex, dt).ok);
    const StepStatus st = implicit_step<2>(im.model, across(), im.state, ws_im, dt);
    ASSERT_TRUE(st.ok) << st.cause;
  }
  const VecD<2> rise = mean_position<2>(ex.state, ex.tip) - start;
  const VecD<2> apart = mean_position<2>(im.state, im.tip) - mean_position<2>(ex.state, ex.tip);
  std::printf("after 1000 steps the tip rose %.4f mm; implicit - explicit: %.2e mm\n", rise.y() * 1e3,
              apart.norm() * 1e3);
  EXPECT_GT(rise.y(), 1e-4);
  EXPECT_LT(apart.norm(), 5e-3 * rise.norm());
}

TEST(MpmImplicit, AStiffCatheterRunsAtAHundredTimesTheExplicitStep) {
  // The explicit step blows up at 100 times its bound; the implicit one settles the catheter there, in a hundredth of
  // the steps. Its settled tip is printed beside the explicit one's (docs/mpm.md: the two differ by 12 %, and the
  // explicit step differs from itself at half its step: MPM's rests form a continuum, and the path picks one).
  Cantilever<2> ex = make_cantilever<2>(stiff_catheter());
  Cantilever<2> big = ex;
  Cantilever<2> im = ex;
  const double dt = 100.0 * ex.model.stable_step(0.4);
  MpmWorkspace<2> ws_big;
  bool exploded = false;
  for (int k = 0; k < 200 && !exploded; ++k) exploded = !step<2>(big.model, across(), big.state, ws_big, dt).ok;
  EXPECT_TRUE(exploded);
  SettleOptions o;
  o.tolerance = 1e-6;  // 0.01 % of L over the window
  o.window = 0.005;
  o.max_time = 0.3;
  MpmWorkspace<2> ws_ex, ws_im;
  const auto t0 = std::chrono::steady_clock::now();
  const SettleResult r_ex = settle<2>(
      ex.model, ex.state, ws_ex, [](double) { return across(); }, ex.tip, o);
  const auto t1 = std::chrono::steady_clock::now();
  o.implicit = true;
  o.time_step = dt;
  const SettleResult r_im = settle<2>(
      im.model, im.state, ws_im, [](double) { return across(); }, im.tip, o);
  const auto t2 = std::chrono::steady_clock::now();
  ASSERT_TRUE(r_ex.status.ok) << r_ex.status.cause;
  ASSERT_TRUE(r_im.status.ok) << r_im.status.cause;
  EXPECT_TRUE(r_ex.settled);
  EXPECT_TRUE(r_im.settled);
  EXPECT_LE(100 * r_im.steps, r_ex.steps + 100);
  const VecD<2> start = mean_position<2>(make_cantilever<2>(stiff_catheter()).state, ex.tip);
  const VecD<2> tip_ex = mean_position<2>(ex.state, ex.tip) - start,
                tip_im = mean_position<2>(im.state, im.tip) - start;
  std::printf(
      "explicit: %ld steps, %.2f s, tip moved (%.4f, %.4f) mm; implicit: %ld steps (%ld Newton, %ld CG), "
      "%.2f s, tip moved (%.4f, %.4f) mm\n",
      r_ex.steps, std::chrono::duration<double>(t1 - t0).count(), tip_ex.x() * 1e3, tip_ex.y() * 1e3, r_im.steps,
      r_im.newton, r_im.cg, std::chrono::duration<double>(t2 - t1).count(), tip_im.x() * 1e3, tip_im.y() * 1e3);
  EXPECT_GT(tip_im.y(), 0.1 * stiff_catheter().length);  // bent towards the field, a large deflection

  // The two settled shapes differ by 12 % of the rise (docs/mpm.md: MPM's equilibria form a continuum, and the loading
  // path picks one), but each is an equilibrium of the other integrator: the implicit step's stationarity at v = 0 is
  // the explicit step's force balance. Continued for 20 ms with the other step, each tip moves less than 1 % of its
  // rise, a twelfth of the gap (measured: 0.43 % for the explicit rest, which still creeps 0.16 % under its own step,
  // and 0.02 % for the implicit rest). The check is this test's own control: handed over with the field 5 % weaker,
  // the explicit rest must move by more than 1 % (a load the two steps disagreed on by that much would be seen).
  auto drift = [&](Cantilever<2>& c, bool implicit, double field_scale = 1.0) {
    const VecD<2> before = mean_position<2>(c.state, c.tip);
    MpmWorkspace<2> ws;
    AppliedField b = across();
    b.uniform *= field_scale;
    const double h = implicit ? dt : c.model.stable_step(0.4);
    for (double t = 0.0; t < 0.02; t += h) {
      const StepStatus st =
          implicit ? implicit_step<2>(c.model, b, c.state, ws, h) : step<2>(c.model, b, c.state, ws, h);
      EXPECT_TRUE(st.ok) << st.cause;
      if (!st.ok) break;
    }
    return (mean_position<2>(c.state, c.tip) - before).norm();
  };
  Cantilever<2> own = ex;
  Cantilever<2> weaker = ex;
  const double creep = drift(own, false);
  const double control = drift(weaker, true, 0.95);
  const double moved_ex = drift(ex, true), moved_im = drift(im, false);
  std::printf(
      "continued for 20 ms with the other step: the explicit rest moved %.2e mm (with its own step: %.2e mm; in a "
      "field 5 %% weaker: %.2e mm), the implicit rest %.2e mm\n",
      moved_ex * 1e3, creep * 1e3, control * 1e3, moved_im * 1e3);
  EXPECT_LT(moved_ex, 1e-2 * tip_ex.norm());
  EXPECT_LT(moved_im, 1e-2 * tip_im.norm());
  EXPECT_GT(control, 1e-2 * tip_ex.norm());
}

}  // namespace
}  // namespace magvine::mpm
