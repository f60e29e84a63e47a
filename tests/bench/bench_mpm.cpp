// MPM throughput (DESIGN.md target: 3D magnetic MPM ≥ 10 M particle-steps/s on 2 cores). The body is the 60 × 3 × 3 mm
// NdFeB–Dragon Skin beam of thesis 3.6.4 (G 120 kPa, Br 0.125 T), clamped, under gravity and a 10 mT field across
// it, sampled at 2 particles per cell per axis; the beam is first bent for 2000 steps so the particles are no longer
// on the lattice. Each iteration is 10 steps; the counter is particle-steps per second. Arg: threads.

#include <benchmark/benchmark.h>
#include <omp.h>

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

}  // namespace

BENCHMARK(BM_MpmBeam3D)->Args({6, 1})->Args({6, 2})->Args({10, 2})->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
