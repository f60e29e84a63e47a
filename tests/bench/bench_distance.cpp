// DistanceQuery on the real CT airway lidc0525 (195k triangles, mm): BVH build time, point distances and capsule
// distances per second on one thread, for each bounding volume, split rule and traversal (magvine's direct
// traversal vs fcl::distance), with and without the warm start.
//
// Query points lie inside the lumen: a random triangle's centroid moved 0.5–5 mm against its outward normal
// (deterministic RNG). "random" takes them in random order (every query lands somewhere else in the tree, as for
// scattered probes); "coherent" builds them over consecutive triangles, whose marching-cubes order is spatially
// coherent, a proxy for successive robot nodes. Capsules: 2 mm segments in a random direction from those points,
// radius 0.5 mm (a vine robot segment); the counter `hit` is the fraction touching the wall. The last entry checks
// the accuracy of FCL's own segment distance (GJK) against the exact direct traversal.
//
//   cmake --build build-fcl --target bench_distance && build-fcl/tests/bench/bench_distance
//   (filter e.g. --benchmark_filter='point/aabb'; the airway comes from ../shared/airways or $MAGVINE_AIRWAYS_DIR)

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "magvine/anatomy/distance_query.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "support/airways.hpp"

namespace {

using magvine::Vec3;
using namespace magvine::anatomy;

constexpr const char* kAirway = "lidc0525_medmpd_p5_airway_mc.stl";
constexpr std::size_t kQueries = 100000;

/// The airway mesh, read once (nullopt when the file is absent).
const std::optional<TriangleMesh>& airway() {
  static const std::optional<TriangleMesh> mesh = []() -> std::optional<TriangleMesh> {
    const auto path = test::airway_file(kAirway);
    if (!path) return std::nullopt;
    return import_mesh(*path).mesh;  // default units: mm
  }();
  return mesh;
}

/// Inside-lumen query points: centroid − outward unit normal × U(0.5, 5) mm. `coherent`: consecutive triangles
/// starting at a random one; otherwise random triangles.
std::vector<Vec3> lumen_points(const TriangleMesh& mesh, bool coherent, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, mesh.triangles.size() - 1);
  std::uniform_real_distribution<double> depth(0.5e-3, 5e-3);
  std::vector<Vec3> points;
  points.reserve(kQueries);
  std::size_t t = pick(rng);
  while (points.size() < kQueries) {
    t = coherent ? (t + 1) % mesh.triangles.size() : pick(rng);
    const Vec3 n = area_vector(mesh, t);
    if (!(n.norm() > 0.0)) continue;
    const Vec3 centroid = (corner(mesh, t, 0) + corner(mesh, t, 1) + corner(mesh, t, 2)) / 3.0;
    points.push_back(centroid - depth(rng) * n.normalized());
  }
  return points;
}

const std::vector<Vec3>& points(bool coherent) {
  static const std::vector<Vec3> random = lumen_points(*airway(), false, 1);
  static const std::vector<Vec3> ordered = lumen_points(*airway(), true, 2);
  return coherent ? ordered : random;
}

/// One hierarchy per option set, built on first use (Google Benchmark calls each function several times).
const DistanceQuery& query(const DistanceQueryOptions& o) {
  static std::map<std::tuple<int, int, int>, std::unique_ptr<DistanceQuery>> cache;
  auto& slot = cache[{static_cast<int>(o.bv), static_cast<int>(o.split), static_cast<int>(o.traversal)}];
  if (!slot) slot = std::make_unique<DistanceQuery>(*airway(), o);
  return *slot;
}

bool skip_without_airway(benchmark::State& state) {
  if (airway()) return false;
  state.SkipWithError("lidc0525_medmpd_p5_airway_mc.stl not found (../shared/airways or $MAGVINE_AIRWAYS_DIR)");
  return true;
}

void bench_build(benchmark::State& state, DistanceQueryOptions options) {
  if (skip_without_airway(state)) return;
  for (auto _ : state) {
    DistanceQuery q(*airway(), options);
    benchmark::DoNotOptimize(q.tree_depth());
  }
  const DistanceQuery q(*airway(), options);
  state.counters["triangles"] = static_cast<double>(q.num_triangles());
  state.counters["depth"] = q.tree_depth();
}

void bench_points(benchmark::State& state, DistanceQueryOptions options, bool warm, bool coherent) {
  if (skip_without_airway(state)) return;
  const DistanceQuery& q = query(options);
  const std::vector<Vec3>& p = points(coherent);
  DistanceWorkspace ws = q.make_workspace();
  ws.warm_start = warm;
  std::size_t i = 0;
  double sum = 0.0;
  for (auto _ : state) {
    sum += q.nearest_point(p[i], ws).distance;
    i = i + 1 == p.size() ? 0 : i + 1;
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

void bench_capsules(benchmark::State& state, DistanceQueryOptions options, bool warm, bool coherent) {
  if (skip_without_airway(state)) return;
  const DistanceQuery& q = query(options);
  const std::vector<Vec3>& a = points(coherent);
  std::vector<Vec3> b(a.size());
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  for (std::size_t k = 0; k < a.size(); ++k) b[k] = a[k] + 2e-3 * Vec3(n01(rng), n01(rng), n01(rng)).normalized();
  constexpr double kRadius = 0.5e-3;
  DistanceWorkspace ws = q.make_workspace();
  ws.warm_start = warm;
  std::size_t i = 0, hits = 0, n = 0;
  for (auto _ : state) {
    hits += q.capsule_distance(a[i], b[i], kRadius, ws).intersects ? 1 : 0;
    ++n;
    i = i + 1 == a.size() ? 0 : i + 1;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
  state.counters["hit"] = n > 0 ? static_cast<double>(hits) / static_cast<double>(n) : 0.0;
}

/// Not a speed measurement: how far FCL's segment path (GJK) is from the exact direct traversal on the airway,
/// over 20 000 segments of 1.4 mm from the random lumen points. Counters: segments crossing the wall (exact),
/// crossings FCL missed, false crossings FCL reported, largest distance error elsewhere [m].
void bench_fcl_segment_accuracy(benchmark::State& state) {
  if (skip_without_airway(state)) return;
  const DistanceQuery& exact = query({DistanceBv::kAabb, DistanceSplit::kMean, DistanceTraversal::kDirect});
  const DistanceQuery& gjk = query({DistanceBv::kRss, DistanceSplit::kMean, DistanceTraversal::kFcl});
  const std::vector<Vec3>& a = points(false);
  DistanceWorkspace ws_exact = exact.make_workspace(), ws_gjk = gjk.make_workspace();
  double crossings = 0, missed = 0, false_crossings = 0, max_error = 0;
  for (auto _ : state) {
    for (std::size_t k = 0; k < 20000; ++k) {
      const Vec3 b = a[k] + Vec3(1e-3, 1e-3, 0.0);
      const CapsuleDistance e = exact.capsule_distance(a[k], b, 0.0, ws_exact);
      const CapsuleDistance f = gjk.capsule_distance(a[k], b, 0.0, ws_gjk);
      crossings += e.axis_crosses_wall ? 1 : 0;
      missed += e.axis_crosses_wall && !f.axis_crosses_wall ? 1 : 0;
      false_crossings += !e.axis_crosses_wall && f.axis_crosses_wall ? 1 : 0;
      if (!e.axis_crosses_wall && !f.axis_crosses_wall) {
        max_error = std::max(max_error, std::abs(f.axis_distance - e.axis_distance));
      }
    }
  }
  const double runs = static_cast<double>(state.iterations());
  state.counters["crossings"] = crossings / runs;
  state.counters["missed"] = missed / runs;
  state.counters["false"] = false_crossings / runs;
  state.counters["max_err_m"] = max_error;
}

const char* name(DistanceBv bv) {
  switch (bv) {
    case DistanceBv::kAabb: return "aabb";
    case DistanceBv::kRss: return "rss";
    case DistanceBv::kObbRss: return "obbrss";
  }
  return "?";
}

const char* name(DistanceSplit split) {
  switch (split) {
    case DistanceSplit::kMean: return "mean";
    case DistanceSplit::kMedian: return "median";
    case DistanceSplit::kBvCenter: return "bvcenter";
  }
  return "?";
}

std::string label(const DistanceQueryOptions& o) {
  return std::string(name(o.bv)) + "/" + name(o.split) + "/" +
         (o.traversal == DistanceTraversal::kDirect ? "direct" : "fcl");
}

void register_all() {
  using B = DistanceBv;
  using S = DistanceSplit;
  using T = DistanceTraversal;
  for (const B bv : {B::kAabb, B::kRss, B::kObbRss}) {
    for (const S split : {S::kMean, S::kMedian, S::kBvCenter}) {
      const DistanceQueryOptions o{bv, split, T::kDirect};
      benchmark::RegisterBenchmark(("build/" + label(o)).c_str(), bench_build, o)
          ->Unit(benchmark::kMillisecond)
          ->Iterations(3);
    }
  }
  // Every BV and split with the direct traversal, and FCL's own traversal where it exists (RSS, OBBRSS).
  std::vector<DistanceQueryOptions> configurations;
  for (const B bv : {B::kAabb, B::kRss, B::kObbRss}) {
    for (const S split : {S::kMean, S::kMedian, S::kBvCenter}) configurations.push_back({bv, split, T::kDirect});
  }
  for (const B bv : {B::kRss, B::kObbRss}) configurations.push_back({bv, S::kMean, T::kFcl});
  for (const DistanceQueryOptions& o : configurations) {
    for (const bool coherent : {false, true}) {
      for (const bool warm : {true, false}) {
        const std::string suffix = std::string(coherent ? "/coherent" : "/random") + (warm ? "/warm" : "/cold");
        benchmark::RegisterBenchmark(("point/" + label(o) + suffix).c_str(), bench_points, o, warm, coherent)
            ->Unit(benchmark::kMicrosecond);
      }
    }
  }
  for (const DistanceQueryOptions& o :
       {DistanceQueryOptions{B::kAabb, S::kMean, T::kDirect}, DistanceQueryOptions{B::kRss, S::kMean, T::kDirect},
        DistanceQueryOptions{B::kRss, S::kMean, T::kFcl}}) {
    for (const bool coherent : {false, true}) {
      const std::string suffix = coherent ? "/coherent/warm" : "/random/warm";
      benchmark::RegisterBenchmark(("capsule/" + label(o) + suffix).c_str(), bench_capsules, o, true, coherent)
          ->Unit(benchmark::kMicrosecond);
    }
  }
  benchmark::RegisterBenchmark("accuracy/segment/rss/mean/fcl_vs_direct", bench_fcl_segment_accuracy)
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
}

}  // namespace

int main(int argc, char** argv) {
  register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
