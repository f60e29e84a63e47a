// Airway graph extraction (issue 8; target: a 200k-triangle airway in ≤ 10 s on one core): the CT airway lidc0525
// (195k triangles of raw marching cubes) when ../shared/airways is there, else the generated bronchial tree (Weibel A
// to generation 6), at the automatic voxel size. Counters: voxel [mm], lumen voxels, branches, leaves.
//
//   cmake --build build-bench --target bench_centerline && build-bench/tests/bench/bench_centerline

#include <benchmark/benchmark.h>

#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "support/airways.hpp"

namespace {

using namespace magvine::anatomy;

void BM_Graph(benchmark::State& state) {
  TriangleMesh mesh;
  std::string label;
  if (const auto path = test::airway_file("lidc0525_medmpd_p5_airway_mc.stl")) {
    mesh = import_mesh(*path).mesh;
    label = "lidc0525";
  } else {
    mesh = make_bronchial_tree({}).mesh;
    label = "generated tree (airway absent)";
  }
  CenterlineReport report;
  AirwayGraph graph;
  for (auto _ : state) {
    graph = extract_airway_graph(mesh, {}, &report);
    benchmark::DoNotOptimize(graph.nodes.data());
  }
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
  state.counters["voxel_mm"] = 1e3 * report.voxel;
  state.counters["lumen_voxels"] = static_cast<double>(report.inside_voxels);
  state.counters["branches"] = static_cast<double>(graph.branches.size());
  state.counters["leaves"] = static_cast<double>(leaves(graph).size());
  state.SetLabel(label);
}
BENCHMARK(BM_Graph)->Unit(benchmark::kSecond)->Iterations(3)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
