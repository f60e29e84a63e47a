// The design's iterations (DESIGN.md target: one design iteration, equilibrium + adjoint, of the 5-section catheter
// ≤ 5 ms; the thesis's magneticMPM took 20–25 s per evaluation). The catheter of assets/scenes/design_catheter.yaml
// (40 × Ø4 mm, 40 edges, 5 sections, 20 mT), its S target, a seeded random design; each equilibrium from the straight
// rod, as the design solves it:
//   /gradient   J and its adjoint gradient (one equilibrium, one block-LDLT solve);
//   /jacobian   the residuals and their Jacobian (one equilibrium, one factorisation, a back-substitution per
//   parameter); /value      J alone (what the Bayesian baseline pays per evaluation); /design     a whole
//   Levenberg–Marquardt design of the S from that start (counter `evaluations`).
//
//   cmake --build build --target bench_design && build/tests/bench/bench_design

#include <benchmark/benchmark.h>

#include <cmath>

#include "magvine/core/units.hpp"
#include "magvine/design/design.hpp"
#include "magvine/studies/design_study.hpp"

namespace {

using namespace magvine;
using namespace magvine::design;

/// The S of design_catheter.yaml: ±90° over each half, in the field's plane.
DesignProblem catheter() {
  DesignProblem p = studies::thesis_catheter_problem();
  const double l = p.model.length;
  p.spec.target = studies::curve_target(l, 9, [l](double s) { return Vec3(0, (s < l / 2 ? 1.0 : -1.0) * kPi / l, 0); });
  return p;
}

void gradient(benchmark::State& state) {
  const DesignProblem p = catheter();
  DesignObjective o(p);
  const VecX x = o.parameters_of(random_design(p, 1));
  const VecX y = x.array() + 1e-3;  // two designs in turn: the objective does not solve the last p again
  VecX g;
  bool odd = false;
  for (auto _ : state) benchmark::DoNotOptimize(o.evaluate((odd = !odd) ? x : y, &g));
}

void jacobian(benchmark::State& state) {
  const DesignProblem p = catheter();
  DesignObjective o(p);
  const VecX x = o.parameters_of(random_design(p, 1));
  const VecX y = x.array() + 1e-3;
  VecX r;
  MatX j;
  bool odd = false;
  for (auto _ : state) benchmark::DoNotOptimize(o.residuals((odd = !odd) ? x : y, r, &j));
}

void value(benchmark::State& state) {
  const DesignProblem p = catheter();
  DesignObjective o(p);
  const VecX x = o.parameters_of(random_design(p, 1));
  const VecX y = x.array() + 1e-3;
  bool odd = false;
  for (auto _ : state) benchmark::DoNotOptimize(o.evaluate((odd = !odd) ? x : y, nullptr));
}

void whole_design(benchmark::State& state) {
  const DesignProblem p = catheter();
  int evaluations = 0;
  double rms = 0.0;
  for (auto _ : state) {
    const DesignResult r = least_squares_design(p, random_design(p, 1), {});
    evaluations = r.evaluations;
    rms = r.rms;
  }
  state.counters["evaluations"] = evaluations;
  state.counters["rms_mm"] = rms * 1e3;
}

BENCHMARK(gradient)->Name("design/gradient")->Unit(benchmark::kMillisecond);
BENCHMARK(jacobian)->Name("design/jacobian")->Unit(benchmark::kMillisecond);
BENCHMARK(value)->Name("design/value")->Unit(benchmark::kMillisecond);
BENCHMARK(whole_design)->Name("design/design")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
