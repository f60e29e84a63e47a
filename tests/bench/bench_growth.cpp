// Vine growth through anatomy (DESIGN.md target: 100 mm of growth through a bronchial tree with contacts ≤ 0.1 s on
// one core, ≥ 1000× faster than the thesis's 60–125 s bench navigations). The thesis's Ø5 mm magnetic-fluid vine
// (TPE 38 µm, 35 kPa, yield 20 kPa here), no field; each iteration grows a fresh vine from 5 mm to 105 mm:
//   /trachea  the generated bronchial tree (Weibel A to generation 4, 0.5 mm meshing, ~0.58 M triangles), the vine
//             started 3 mm off the trachea's axis with gravity across it, so it grows lying on the wall;
//   /carina   the same tree, the vine started 70 mm down the trachea leaning on its wall: it grows past the carina
//             and 35 mm into the main bronchus on its side (the "through the tree");
//   /y        the Y bifurcation phantom (parent Ø12 mm, daughters Ø9.5 mm at 35°, ~0.31 M triangles), the vine
//             started against one side wall and leaning that way: it turns into that daughter.
// The barrier contact (docs/growth-and-contact.md). Counters: steps (advance calls of 20 ms), Newton iterations,
// solves (the friction lag's), nodes on the wall at the end.
//
//   cmake --build build-bench --target bench_growth && build-bench/tests/bench/bench_growth

#include <benchmark/benchmark.h>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/robot/growth.hpp"
#include "magvine/studies/growth_study.hpp"

namespace {

using namespace magvine;
using namespace magvine::robot;

VineParameters fluid_vine() { return thesis_fluid_vine(5e-3); }

void grow(benchmark::State& state, const anatomy::CollisionWorld& world, const Vec3& gravity, const Vec3& base,
          const Mat3& frame) {
  GrowthOptions o;
  o.gravity = gravity;
  o.law.yield_pressure = 20e3;
  int steps = 0;
  int newton = 0;
  int passes = 0;  // solves
  int contacts = 0;
  for (auto _ : state) {
    VineGrowth g(fluid_vine(), o, &world, {}, base, frame);
    steps = newton = passes = 0;
    while (g.length() < 105e-3) {
      const GrowthStatus r = g.advance(0.02, {.pressure = 35e3});
      ++steps;
      newton += r.newton_iterations;
      passes += r.solves;
      if (!r.converged || g.time() > 30.0) {
        state.SkipWithError("growth stopped");
        break;
      }
    }
    contacts = g.wall_forces().nodes_in_contact;
    benchmark::DoNotOptimize(g.state().tip());
  }
  state.counters["steps"] = steps;
  state.counters["newton"] = newton;
  state.counters["solves"] = passes;
  state.counters["contacts"] = contacts;
}

/// The generated tree to generation 4 at 0.5 mm meshing, the growth study's (built once).
const anatomy::CollisionWorld& tree() { return studies::growth_study_world(studies::GrowthStudyCase::kCarina); }

void BM_GrowthTrachea(benchmark::State& state) {
  Mat3 frame;  // tangent down the trachea (−z), normal +x
  frame.col(0) = -Vec3::UnitZ();
  frame.col(1) = Vec3::UnitX();
  frame.col(2) = frame.col(0).cross(frame.col(1));
  grow(state, tree(), Vec3(9.81, 0.0, 0.0), Vec3(3e-3, 0.0, -5e-3), frame);
}

void BM_GrowthCarina(benchmark::State& state) {
  Mat3 frame;
  frame.col(0) = -Vec3::UnitZ();
  frame.col(1) = Vec3::UnitX();
  frame.col(2) = frame.col(0).cross(frame.col(1));
  grow(state, tree(), Vec3(9.81, 0.0, 0.0), Vec3(3e-3, 0.0, -70e-3), frame);
}

void BM_GrowthY(benchmark::State& state) {
  grow(state, studies::growth_study_world(studies::GrowthStudyCase::kY), Vec3(0.0, 9.81, 0.0), Vec3(2e-3, 3e-3, 0.0), Mat3::Identity());
}

}  // namespace

BENCHMARK(BM_GrowthTrachea)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_GrowthCarina)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_GrowthY)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK_MAIN();
