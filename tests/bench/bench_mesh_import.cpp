// Import + weld + collision-world build of a 1M-triangle airway mesh (DESIGN.md target: ≤ 3 s on one core), and the
// diagnostics of `magvine mesh check` on the same mesh.
//
// The 1M-triangle input is made from real CT surfaces when ../shared/airways is present: LIDC-IDRI-0525 and the
// silicone phantom, each split 1 → 4 by edge midpoints (same shape, 4× the triangles), side by side in one binary
// STL of 1.08 M triangles. Without the shared folder, a 1 M-triangle tube stands in.

#include <benchmark/benchmark.h>

#include <filesystem>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "support/airways.hpp"

namespace {

using magvine::Vec3;
using namespace magvine::anatomy;

// Splits every triangle into four at its edge midpoints (shared midpoints are duplicated here; import welds them).
TriangleMesh subdivide(const TriangleMesh& mesh) {
  TriangleMesh out;
  out.vertices.reserve(6 * mesh.triangles.size());
  for (const Triangle& t : mesh.triangles) {
    const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const auto base = static_cast<std::uint32_t>(out.vertices.size());
    for (const Vec3& p : {a, b, c, Vec3(0.5 * (a + b)), Vec3(0.5 * (b + c)), Vec3(0.5 * (c + a))}) {
      out.vertices.push_back(p);
    }
    out.triangles.push_back({base, base + 3, base + 5});
    out.triangles.push_back({base + 3, base + 1, base + 4});
    out.triangles.push_back({base + 5, base + 4, base + 2});
    out.triangles.push_back({base + 3, base + 4, base + 5});
  }
  return out;
}

void append(TriangleMesh& to, const TriangleMesh& from, const Vec3& shift) {
  const auto base = static_cast<std::uint32_t>(to.vertices.size());
  for (const Vec3& p : from.vertices) to.vertices.push_back(p + shift);
  for (const Triangle& t : from.triangles) to.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

// Writes the 1M-triangle STL once per process and returns its path.
const std::filesystem::path& million_triangle_stl() {
  static const std::filesystem::path path = [] {
    const auto file = std::filesystem::temp_directory_path() / "magvine_bench_1m.stl";
    TriangleMesh big;
    const auto lidc = test::airway_file("lidc0525_medmpd_p5_airway_mc.stl");
    const auto silicone = test::airway_file("siliconmodel3_airway.stl");
    if (lidc && silicone) {
      append(big, subdivide(import_mesh(*lidc).mesh), Vec3::Zero());
      append(big, subdivide(import_mesh(*silicone).mesh), Vec3(0.3, 0.0, 0.0));
    } else {
      big = make_tube({.radius = 9e-3, .length = 0.12, .segments = 1000, .rings = 501, .capped = true});
    }
    write_stl(file, big);
    return file;
  }();
  return path;
}

void BM_ImportWeld(benchmark::State& state) {
  const auto& file = million_triangle_stl();
  std::size_t triangles = 0;
  for (auto _ : state) {
    const ImportedMesh in = import_mesh(file);
    triangles = in.mesh.triangles.size();
    benchmark::DoNotOptimize(in.mesh.vertices.data());
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}

void BM_ImportWeldCollisionWorld(benchmark::State& state) {
  const auto& file = million_triangle_stl();
  std::size_t triangles = 0;
  for (auto _ : state) {
    const ImportedMesh in = import_mesh(file);
    const CollisionWorld world(in.mesh);
    triangles = in.mesh.triangles.size();
    benchmark::DoNotOptimize(&world);
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}

void BM_MeshReport(benchmark::State& state) {
  const ImportedMesh in = import_mesh(million_triangle_stl());
  for (auto _ : state) {
    const MeshReport report = analyse_mesh(in.mesh);
    benchmark::DoNotOptimize(report.genus);
  }
  state.counters["triangles"] = static_cast<double>(in.mesh.triangles.size());
}

BENCHMARK(BM_ImportWeld)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_ImportWeldCollisionWorld)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_MeshReport)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
