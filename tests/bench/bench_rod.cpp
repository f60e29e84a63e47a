// Static equilibrium of the discretised rod (DESIGN.md target: 100 nodes under magnetic + gravity loads ≤ 1 ms).
// The acceptance beam of issue 4 (60 × 3 × 3 mm, G 120 kPa, Br 0.125 T, ρ 1882 kg/m³), clamped horizontally,
// gravity on, from the straight state each time:
//   /uniform  10 mT perpendicular to the beam;
//   /dipole   the thesis EPM (N52, Ø101.6 × 101.6 mm) as a dipole 200 mm below the midpoint (its curvature, the
//             Hessian's field term, in closed form);
//   /cylinder the same EPM with its exact cylinder field (curvature from differences of the field gradient);
//   /dipole warm  the same, each solve starting from the previous equilibrium with the EPM moved by 1 mm;
//                 second argument 1: with a RodWorkspace (the previous Hessian reused for chord steps);
//   /cylinder warm  the same with the exact cylinder field of the EPM.
// Counter `iterations` = Newton iterations per solve.
//
//   cmake --build build-bench --target bench_rod && build-bench/tests/bench/bench_rod

#include <benchmark/benchmark.h>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/robot/rod.hpp"

namespace {

using namespace magvine;
using namespace magvine::robot;

void bench(benchmark::State& state, const RodField& field) {
  const int edges = static_cast<int>(state.range(0));
  RodModel m = rectangular_rod(60e-3, 3e-3, 3e-3, 120e3, 1882.0, 0.125, Vec3::UnitX(), edges);
  m.gravity = Vec3(0.0, -9.81, 0.0);
  int iterations = 0;
  for (auto _ : state) {
    RodState s = straight_rod(m);
    const RodSolveReport r = solve_rod_statics(m, field, s);
    if (!r.converged) state.SkipWithError(r.failure.c_str());
    iterations = r.iterations;
    benchmark::DoNotOptimize(s.x.back());
  }
  state.counters["iterations"] = iterations;
}

void BM_RodUniform(benchmark::State& state) {
  bench(state, [](const Vec3&) {
    magnetics::FieldSample f;
    f.b = Vec3(0.0, 10e-3, 0.0);
    return f;
  });
}

void BM_RodDipole(benchmark::State& state) {
  const double radius = 50.8e-3;
  magnetics::FieldModel magnets;
  magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 1.45 * kPi * radius * radius * 2.0 * radius / kMu0)},
              magnetics::Pose::from_axis(Vec3(30e-3, -0.2, 0.0), Vec3::UnitY()));
  bench(state, field_function(magnets, magnets.rest_poses));
}

void BM_RodCylinder(benchmark::State& state) {
  const double radius = 50.8e-3;
  magnetics::FieldModel magnets;
  magnets.add(magnetics::CylinderMagnet(radius, 2.0 * radius, Vec3(0.0, 0.0, 1.45)),
              magnetics::Pose::from_axis(Vec3(30e-3, -0.2, 0.0), Vec3::UnitY()));
  bench(state, field_function(magnets, magnets.rest_poses));
}

/// Warm start, as in a simulation loop: the EPM moves 1 mm between solves (alternating between two positions) and
/// each equilibrium starts from the previous one. `exact`: the exact cylinder field instead of the dipole.
void warm(benchmark::State& state, bool exact) {
  const int edges = static_cast<int>(state.range(0));
  RodModel m = rectangular_rod(60e-3, 3e-3, 3e-3, 120e3, 1882.0, 0.125, Vec3::UnitX(), edges);
  m.gravity = Vec3(0.0, -9.81, 0.0);
  const double radius = 50.8e-3;
  RodField fields[2];
  for (int k = 0; k < 2; ++k) {
    magnetics::FieldModel magnets;
    const magnetics::Pose pose = magnetics::Pose::from_axis(Vec3(30e-3 + 1e-3 * k, -0.2, 0.0), Vec3::UnitY());
    if (exact) {
      magnets.add(magnetics::CylinderMagnet(radius, 2.0 * radius, Vec3(0.0, 0.0, 1.45)), pose);
    } else {
      magnets.add(magnetics::DipoleSource{Vec3(0.0, 0.0, 1.45 * kPi * radius * radius * 2.0 * radius / kMu0)}, pose);
    }
    fields[k] = field_function(magnets, magnets.rest_poses);
  }
  RodState s = straight_rod(m);
  RodWorkspace workspace;
  RodWorkspace* ws = state.range(1) != 0 ? &workspace : nullptr;
  if (!solve_rod_statics(m, fields[0], s, {}, ws).converged) state.SkipWithError("cold solve failed");
  int k = 1;
  int iterations = 0;
  int hessians = 0;
  int solves = 0;
  for (auto _ : state) {
    const RodSolveReport r = solve_rod_statics(m, fields[k], s, {}, ws);
    if (!r.converged) state.SkipWithError(r.failure.c_str());
    iterations += r.iterations;
    hessians += r.hessians;
    ++solves;
    k = 1 - k;
    benchmark::DoNotOptimize(s.x.back());
  }
  state.counters["iterations"] = solves > 0 ? static_cast<double>(iterations) / solves : 0.0;
  state.counters["hessians"] = solves > 0 ? static_cast<double>(hessians) / solves : 0.0;
}

void BM_RodDipoleWarm(benchmark::State& state) { warm(state, false); }
void BM_RodCylinderWarm(benchmark::State& state) { warm(state, true); }

}  // namespace

BENCHMARK(BM_RodUniform)->Arg(100)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RodDipole)->Arg(100)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RodCylinder)->Arg(100)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RodDipoleWarm)->Args({100, 0})->Args({100, 1})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RodCylinderWarm)->Args({100, 0})->Args({100, 1})->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
