// Field + gradient throughput, single core (DESIGN.md targets: dipole ≥ 20 M/s, exact cylinder ≥ 1 M/s).
// Points are spread over the EPM's working range (100–300 mm, all directions) so the cel iterations are typical.

#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "magvine/magnetics/field_model.hpp"

namespace {

using magvine::Mat3;
using magvine::Vec3;
using namespace magvine::magnetics;

std::vector<Vec3> working_points(std::size_t n) {
  std::mt19937 rng(42);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> r(0.1, 0.3);
  std::vector<Vec3> pts(n);
  for (auto& p : pts) p = Vec3(g(rng), g(rng), g(rng)).normalized() * r(rng);
  return pts;
}

void run(benchmark::State& state, const FieldModel& model) {
  const auto pts = working_points(4096);
  std::vector<FieldSample> out(pts.size());
  for (auto _ : state) {
    field_gradient_batch(model, model.rest_poses, pts, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * pts.size()));
}

void BM_DipoleFieldGradient(benchmark::State& state) {
  FieldModel model;
  model.add(DipoleSource{Vec3(0, 0, 970.1)}, Pose{});
  run(state, model);
}

void BM_CylinderAxialFieldGradient(benchmark::State& state) {
  FieldModel model;
  model.add(CylinderMagnet(0.0508, 0.1016, Vec3(0, 0, 1.48)), Pose{});
  run(state, model);
}

void BM_CylinderDiametricFieldGradient(benchmark::State& state) {
  FieldModel model;
  model.add(CylinderMagnet(0.0508, 0.1016, Vec3(1.48, 0, 0)), Pose{});
  run(state, model);
}

void BM_CylinderAxialFieldOnly(benchmark::State& state) {
  const CylinderMagnet c(0.0508, 0.1016, Vec3(0, 0, 1.48));
  const auto pts = working_points(4096);
  for (auto _ : state) {
    for (const auto& p : pts) benchmark::DoNotOptimize(c.field(p));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * pts.size()));
}

}  // namespace

BENCHMARK(BM_DipoleFieldGradient);
BENCHMARK(BM_CylinderAxialFieldGradient);
BENCHMARK(BM_CylinderDiametricFieldGradient);
BENCHMARK(BM_CylinderAxialFieldOnly);
BENCHMARK_MAIN();
