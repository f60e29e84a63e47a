// MPM throughput (DESIGN.md target: 3D magnetic MPM ≥ 10 M particle-steps/s on 2 cores). The body is the 60 × 3 × 3 mm
// NdFeB–Dragon Skin beam of thesis 3.6.4 (G 120 kPa, Br 0.125 T), clamped, under gravity and a 10 mT field across
// it, sampled at 2 particles per cell per axis; the beam is first bent for 2000 steps so the particles are no longer
// on the lattice. Each iteration is 10 steps; the counter is particle-steps per second. Arg: threads.
//
// BM_StiffCatheterSettle: the implicit step's compute against the explicit one's (issue 34, item 4) — a stiff magnetic
// catheter (E ≈ 3 MPa: G 1 MPa, K 20 G; 1 mm thick, 2 cells through it in 3D, 4 in 2D; B̃r 0.1 T along it, 20 mT
// across it, damped near critically) settled from straight until its tip moves < 1e-6 m over 5 ms, one thread.
// Args: dimension, step (0 explicit at courant 0.4, N > 0 implicit at N times that), frame (0 updated-, 1 total-
// Lagrangian). Counters: steps, tip rise [mm], Newton and CG iterations, factorizations.

#include <benchmark/benchmark.h>
#include <omp.h>

#include <utility>

#include "magvine/mpm/cantilever.hpp"

namespace {

using namespace magvine;

mpm::Cantilever<3> beam(int cells) {
  mpm::CantileverSpec s;
  s.length = 60e-3;
  s.thickness = 3e-3;
  s.width = 3e-3;
  s.cells_through_thickness = cells;
  s.particles_per_cell = 2;
  s.material = {120e3, 20.0 * 120e3, 1882.0};
  s.remanence = Vec3(0.125, 0.0, 0.0);
  s.gravity = Vec3(0.0, -9.81, 0.0);
  s.damping = 20.0;
  return mpm::make_cantilever<3>(s);
}

mpm::AppliedField field() {
  mpm::AppliedField f;
  f.kind = mpm::AppliedField::Kind::kUniform;
  f.uniform = Vec3(0.0, 10e-3, 0.0);
  return f;
}

void BM_MpmBeam3D(benchmark::State& state) {
  omp_set_num_threads(static_cast<int>(state.range(1)));
  mpm::Cantilever<3> b = beam(static_cast<int>(state.range(0)));
  mpm::MpmWorkspace<3> ws;
  const double dt = b.model.stable_step(0.4);
  const mpm::AppliedField f = field();
  for (int i = 0; i < 2000; ++i) {
    if (!mpm::step(b.model, f, b.state, ws, dt).ok) state.SkipWithError("the beam failed while bending");
  }
  for (auto _ : state) {
    for (int i = 0; i < 10; ++i) benchmark::DoNotOptimize(mpm::step(b.model, f, b.state, ws, dt).ok);
  }
  state.counters["particles"] = static_cast<double>(b.model.size());
  state.counters["particle_steps_per_s"] =
      benchmark::Counter(10.0 * static_cast<double>(b.model.size()), benchmark::Counter::kIsIterationInvariantRate);
}

template <int D>
void settle_catheter(benchmark::State& state) {
  omp_set_num_threads(1);
  mpm::CantileverSpec s;
  s.length = 10e-3;
  s.thickness = 1e-3;
  s.width = 1e-3;
  s.cells_through_thickness = D == 2 ? 4 : 2;
  s.particles_per_cell = 2;
  s.material = {1e6, 2e7, 1100.0};
  s.remanence = Vec3(0.1, 0.0, 0.0);
  s.damping = 1000.0;
  mpm::AppliedField f;
  f.kind = mpm::AppliedField::Kind::kUniform;
  f.uniform = Vec3(0.0, 20e-3, 0.0);
  mpm::SettleOptions o;
  o.tolerance = 1e-6;
  o.window = 0.005;
  o.max_time = 0.3;
  const long ratio = state.range(1);
  o.implicit = ratio > 0;
  o.total_lagrangian = state.range(2) != 0;
  mpm::SettleResult r;
  double rise = 0.0;
  for (auto _ : state) {
    mpm::Cantilever<D> c = mpm::make_cantilever<D>(s);
    const double start = mpm::mean_position<D>(c.state, c.tip)[1];
    if (o.implicit) o.time_step = static_cast<double>(ratio) * c.model.stable_step(o.courant);
    mpm::MpmWorkspace<D> ws;
    r = mpm::settle<D>(c.model, c.state, ws, [&](double) { return f; }, c.tip, o);
    if (!r.status.ok || !r.settled) state.SkipWithError("the catheter did not settle");
    rise = mpm::mean_position<D>(c.state, c.tip)[1] - start;
  }
  state.counters["steps"] = static_cast<double>(r.steps);
  state.counters["tip_rise_mm"] = rise * 1e3;
  state.counters["newton"] = static_cast<double>(r.newton);
  state.counters["cg"] = static_cast<double>(r.cg);
  state.counters["factorizations"] = static_cast<double>(r.factorizations);
  state.counters["retries"] = static_cast<double>(r.retries);
}

void BM_StiffCatheterSettle(benchmark::State& state) {
  if (state.range(0) == 2)
    settle_catheter<2>(state);
  else
    settle_catheter<3>(state);
}

}  // namespace

BENCHMARK(BM_StiffCatheterSettle)
    ->Apply([](benchmark::internal::Benchmark* b) {  // per frame and dimension: explicit, 10×, and 100× (2D) or 50× (3D)
      for (int frame : {0, 1}) {
        for (const auto& [dim, large] : {std::pair{2, 100}, std::pair{3, 50}}) {
          for (int ratio : {0, 10, large}) b->Args({dim, ratio, frame});
        }
      }
    })
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();
BENCHMARK(BM_MpmBeam3D)->Args({6, 1})->Args({6, 2})->Args({10, 2})->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
