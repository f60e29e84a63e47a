// The platform (docs/platform.md): the LBR iiwa 14's inverse kinematics per solve (a full pose, and a magnet's
// position and axis from where the arm is, as the navigator asks it), one world check of an arm (GJK against the
// torso, the table and the other arm), the holding torques by Bullet's articulated bodies, and the demo run with and
// without the patient and arm (counters: the run's computing and the platform's share of it; ISSUE 30's target:
// the platform adds ≤ 10 % to the demo's compute).
//
//   cmake --build build --target bench_platform && build/tests/bench/bench_platform

#include <benchmark/benchmark.h>

#include <random>

#include "magvine/core/units.hpp"
#include "magvine/platform/platform.hpp"
#include "magvine/scene/experiment.hpp"

namespace {

using namespace magvine;
using namespace magvine::platform;

std::vector<Iso3> random_flange_poses(const ArmModel& arm, int n) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Iso3> poses;
  for (int k = 0; k < n; ++k) {
    JointVector q;
    for (int i = 0; i < kArmJoints; ++i) q[i] = arm.q_min[i] + unit(rng) * (arm.q_max[i] - arm.q_min[i]);
    poses.push_back(flange_pose(arm, Iso3::Identity(), q));
  }
  return poses;
}

void BM_IkFullPose(benchmark::State& state) {
  const ArmModel arm = iiwa14_r820();
  const std::vector<Iso3> poses = random_flange_poses(arm, 256);
  std::size_t k = 0;
  int converged = 0, solves = 0;
  for (auto _ : state) {
    const IkResult r =
        solve_ik(arm, Iso3::Identity(), Iso3::Identity(), poses[k++ % poses.size()], JointVector::Zero());
    converged += r.converged;
    ++solves;
    benchmark::DoNotOptimize(r.q);
  }
  state.counters["converged"] = static_cast<double>(converged) / solves;
}
BENCHMARK(BM_IkFullPose)->Unit(benchmark::kMicrosecond);

PlatformModel patient_and_arm() {
  PlatformModel m;
  m.body = TorsoModel{};
  m.table = TableModel{};
  place_patient(Vec3::Zero(), Vec3(0, 0, -1), Vec3(0, -1, 0), 0.09, *m.body, &*m.table);
  ArmMount a;
  a.base = arm_base_beside(*m.body, *m.table, 1, 0.55, 0.0, Vec3::Zero());
  a.tool.flange_to_magnet.linear() << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  a.tool.flange_to_magnet.translation() = Vec3(0, 0, 0.1008);
  a.tool.mass = 6.18;
  a.tool.com = a.tool.flange_to_magnet.translation();
  m.arms.push_back(a);
  m.gravity = Vec3(0, 9.81, 0);
  return m;
}

void BM_NearPlacement(benchmark::State& state) {
  // The navigator's step: a magnet 1 cm further round the shell, from where the arm holds it (IK near the arm's
  // joints, the pose and the tracker's way there checked in the world).
  const PlatformModel model = patient_and_arm();
  PlatformRun run(model);
  const Vec3 out(0, -1, 0);
  const Vec3 p = *run.shell_point(0, kPi / 2, 0.2);
  run.request(0, p, out, true);
  const Vec3 q = *run.shell_point(0, kPi / 2 + 0.05, 0.2);
  int feasible = 0, n = 0;
  for (auto _ : state) {
    const Placement pl = run.evaluate(0, q, out, true);
    feasible += pl.feasible;
    ++n;
  }
  state.counters["feasible"] = static_cast<double>(feasible) / n;
}
BENCHMARK(BM_NearPlacement)->Unit(benchmark::kMicrosecond);

void BM_WorldCheckAndTorques(benchmark::State& state) {
  const PlatformModel model = patient_and_arm();
  PlatformWorld world(model);
  JointVector q;
  q << 0.3, 0.6, 0.1, -1.2, 0.2, 0.9, 0.1;
  world.set_joints(0, q);
  for (auto _ : state) {
    const ArmCheck c = world.check(0);
    benchmark::DoNotOptimize(c.nearest);
    const JointVector tau = world.holding_torques(0);
    benchmark::DoNotOptimize(tau);
  }
}
BENCHMARK(BM_WorldCheckAndTorques)->Unit(benchmark::kMicrosecond);

void demo(benchmark::State& state, const char* scene_file) {
  const scene::ExperimentScene scene =
      scene::load_experiment_scene(std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes" / scene_file);
  double run = 0.0, platform = 0.0;
  for (auto _ : state) {
    const scene::ExperimentResult r = scene::run_experiment(scene);
    run = r.runtime_s;
    platform = r.platform ? r.platform->compute_s : 0.0;
    benchmark::DoNotOptimize(r.success);
  }
  state.counters["run_s"] = run;
  state.counters["platform_s"] = platform;
  state.counters["platform_share"] = run > 0.0 ? platform / run : 0.0;
}
BENCHMARK_CAPTURE(demo, free_magnet, "bronchial_tree_navigator.yaml")->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK_CAPTURE(demo, patient_and_arm, "bronchial_tree_platform.yaml")->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
