// CT import benchmarks (issue 31), on Med-MPD patient 1 and 5 from ../shared/airways (skipped when absent):
//  - BM_CtSurface / BM_CtImport: a 512 × ~330 × 512 label map to the surface, and to surface + mesh report +
//    airway graph (`magvine ct import`'s work), on one core (OpenVDB's TBB pool limited to one thread). Target
//    ≤ 30 s (issue 31).
//  - BM_SphereContacts/<mesh>: sphere contact queries (Ø3 mm, the bench_contacts radius) at the same points near the
//    wall of the imported, smoothed surface and of the shared marching-cubes (staircase) mesh of the same map: the
//    smoothed surface's triangles are fewer and larger, so a query meets fewer of them.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <array>
#include <random>
#include <string>
#include <vector>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/ct/import.hpp"
#include "support/airways.hpp"

namespace {

using namespace magvine;

constexpr double kRadius = 1.5e-3;

std::optional<std::filesystem::path> segmentation(int patient) {
  return test::airway_file("segmentations/Patient" + std::to_string(patient) + "/bronchialTree.nii.gz");
}

void BM_CtSurface(benchmark::State& state) {
  const auto file = segmentation(static_cast<int>(state.range(0)));
  if (!file) return state.SkipWithError("../shared/airways/segmentations absent");
  const tbb::global_control one_core(tbb::global_control::max_allowed_parallelism, 1);
  std::size_t triangles = 0;
  for (auto _ : state) triangles = ct::import_segmentation(*file, {}).triangles.size();
  state.counters["triangles"] = static_cast<double>(triangles);
}

void BM_CtImport(benchmark::State& state) {
  const auto file = segmentation(static_cast<int>(state.range(0)));
  if (!file) return state.SkipWithError("../shared/airways/segmentations absent");
  const tbb::global_control one_core(tbb::global_control::max_allowed_parallelism, 1);
  ct::ImportResult r;
  for (auto _ : state) r = ct::import_anatomy(*file);
  state.counters["read_s"] = r.surface.seconds_read;
  state.counters["surface_s"] = r.surface.seconds_surface;
  state.counters["report_s"] = r.seconds_report;
  state.counters["graph_s"] = r.seconds_graph;
  state.counters["generations"] = r.deepest_generation;
}

/// Patient 1's imported surface and its marching-cubes mesh, and query points: 20 000 points of the reference
/// surface moved 1 mm into the lumen (spheres of 1.5 mm radius there touch the wall), the same for both meshes.
struct Pair {
  anatomy::TriangleMesh imported, staircase;
  std::vector<Vec3> centres;
};

const Pair* pair() {
  static const std::optional<Pair> p = []() -> std::optional<Pair> {
    const auto file = segmentation(1);
    const auto mc = test::airway_file("lidc0297_medmpd_p1_airway_mc.stl");
    if (!file || !mc) return std::nullopt;
    Pair out;
    out.imported = ct::import_anatomy(*file).mesh.mesh;
    out.staircase = anatomy::import_mesh(*mc).mesh;
    std::mt19937_64 rng(7);
    std::uniform_int_distribution<std::size_t> pick(0, out.staircase.triangles.size() - 1);
    while (out.centres.size() < 20000) {
      const std::size_t t = pick(rng);
      const Vec3 n = anatomy::area_vector(out.staircase, t);
      if (!(n.norm() > 0.0)) continue;
      const Vec3 c = (corner(out.staircase, t, 0) + corner(out.staircase, t, 1) + corner(out.staircase, t, 2)) / 3.0;
      out.centres.push_back(c - 1e-3 * n.normalized());  // outward normals: inward is −n
    }
    return out;
  }();
  return p ? &*p : nullptr;
}

void BM_SphereContacts(benchmark::State& state, bool imported) {
  const Pair* p = pair();
  if (p == nullptr) return state.SkipWithError("../shared/airways absent");
  const anatomy::CollisionWorld world(imported ? p->imported : p->staircase);
  std::array<anatomy::Contact, 8> out{};
  std::size_t i = 0, contacts = 0;
  for (auto _ : state) {
    contacts += world.sphere_contacts(p->centres[i], kRadius, out);
    benchmark::DoNotOptimize(out.data());
    i = i + 1 == p->centres.size() ? 0 : i + 1;
  }
  state.counters["queries_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["contacts"] = static_cast<double>(contacts) / static_cast<double>(state.iterations());
  state.counters["triangles"] = static_cast<double>(world.mesh().triangles.size());
}

}  // namespace

BENCHMARK(BM_CtSurface)->Arg(1)->Arg(5)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_CtImport)->Arg(1)->Arg(5)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_SphereContacts, imported, true)->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(BM_SphereContacts, staircase, false)->Unit(benchmark::kNanosecond);

BENCHMARK_MAIN();
