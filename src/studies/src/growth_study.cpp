#include "magvine/studies/growth_study.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/text.hpp"
#include "magvine/robot/growth.hpp"

namespace magvine::studies {
namespace {

constexpr double kEnd = 105e-3;    // each run grows to this everted length [m] (from about 5 mm: 100 mm of growth)
constexpr double kFirst = 10e-3;   // the tips are compared at everted lengths from this one [m]
constexpr double kSample = 5e-3;   // every this much [m]

/// The tip where the body's everted length was s, interpolated between the samples (length, tip) around it.
Vec3 tip_at(const std::vector<std::pair<double, Vec3>>& path, double s) {
  for (std::size_t k = 1; k < path.size(); ++k) {
    if (path[k].first >= s) {
      const double span = path[k].first - path[k - 1].first;
      const double f = span > 0.0 ? (s - path[k - 1].first) / span : 1.0;
      return path[k - 1].second + f * (path[k].second - path[k - 1].second);
    }
  }
  return path.back().second;
}

}  // namespace

const anatomy::CollisionWorld& growth_study_world(GrowthStudyCase which) {
  if (which == GrowthStudyCase::kY) {  // each world built on first use only
    static const auto y =
        std::make_unique<anatomy::CollisionWorld>(anatomy::make_y_bifurcation(anatomy::YBifurcationParams{}).mesh);
    return *y;
  }
  static const auto tree = [] {
    anatomy::BronchialTreeParams p;
    p.max_generation = 4;
    p.spacing = 0.5e-3;
    return std::make_unique<anatomy::CollisionWorld>(anatomy::make_bronchial_tree(p).mesh);
  }();
  return *tree;
}

GrowthStudyRun run_growth_study_case(GrowthStudyCase which, double edge_length, double dt, double contact_distance) {
  const bool y = which == GrowthStudyCase::kY;
  const anatomy::CollisionWorld& world = growth_study_world(which);
  robot::GrowthOptions o;
  o.gravity = y ? Vec3(0.0, 9.81, 0.0) : Vec3(9.81, 0.0, 0.0);
  o.law.yield_pressure = 20e3;
  o.edge_length = edge_length;
  o.contact_distance = contact_distance;
  const double step = dt > 0.0 ? dt : 0.02;
  Mat3 frame = Mat3::Identity();  // the Y: along its parent (+x)
  if (!y) {  // down the trachea (−z), normal +x
    frame.col(0) = -Vec3::UnitZ();
    frame.col(1) = Vec3::UnitX();
    frame.col(2) = frame.col(0).cross(frame.col(1));
  }
  GrowthStudyRun run;
  run.which = which;
  const Stopwatch clock;
  const Vec3 base = y ? Vec3(2e-3, 3e-3, 0.0) : Vec3(3e-3, 0.0, -70e-3);
  robot::VineGrowth g(robot::thesis_fluid_vine(5e-3), o, &world, {}, base, frame);
  // The initial body is whole edges of about 5 mm (3.75 mm with h = 3.75 mm): the runs are compared at equal
  // everted lengths, not at equal growth.
  const double start = g.length();
  std::vector<std::pair<double, Vec3>> path{{start, g.state().tip()}};
  while (g.length() < kEnd && g.time() < 30.0) {
    const robot::GrowthStatus r = g.advance(step, {.pressure = 35e3});
    ++run.steps;
    run.newton += r.newton_iterations;
    if (!r.converged) {
      run.failure = r.failure;
      break;
    }
    path.emplace_back(g.length(), g.state().tip());
    run.peak_node_normal = std::max(run.peak_node_normal, g.wall_forces().max_normal);
    run.peak_total_normal = std::max(run.peak_total_normal, g.wall_forces().total_normal);
  }
  run.seconds = clock.seconds();
  run.grown = g.length() - start;
  run.ok = run.failure.empty() && g.length() >= kEnd - 1e-9;
  if (!run.ok && run.failure.empty()) run.failure = "grew " + printf_string("%.1f mm", 1e3 * run.grown) + " in 30 s";
  for (double s = kFirst; s <= std::min(g.length(), kEnd) + 1e-12; s += kSample) run.tips.push_back(tip_at(path, s));
  return run;
}

void run_growth_study(const std::filesystem::path& dir, bool quick,
                      const std::function<void(const GrowthStudyRun&)>& progress) {
  const double r = 2.5e-3;  // the vine's made radius (the defaults scale with it)
  struct Sweep {
    const char* knob;
    std::vector<double> values;  // coarse to fine; the last is the reference
  };
  std::vector<Sweep> sweeps;
  if (quick) {
    sweeps.push_back({"edge_length", {r, 0.75 * r}});
    sweeps.push_back({"dt", {0.02, 0.01}});
    sweeps.push_back({"contact_distance", {0.02 * r, 0.01 * r}});
  } else {
    sweeps.push_back({"edge_length", {2.0 * r, 1.5 * r, r, 0.75 * r, 0.5 * r}});
    sweeps.push_back({"dt", {0.04, 0.02, 0.01, 0.005, 0.0025}});
    sweeps.push_back({"contact_distance", {0.08 * r, 0.04 * r, 0.02 * r, 0.01 * r, 0.005 * r}});
  }
  std::string csv =
      "case,knob,value,ok,grown_m,steps,newton,seconds,peak_node_normal_N,peak_total_normal_N,tip_path_error_m,"
      "peak_node_normal_rel_err,peak_total_normal_rel_err,failure\n";
  for (const GrowthStudyCase which : {GrowthStudyCase::kCarina, GrowthStudyCase::kY}) {
    for (const Sweep& sweep : sweeps) {
      std::vector<GrowthStudyRun> runs;
      for (const double v : sweep.values) {
        const std::string knob = sweep.knob;
        GrowthStudyRun run = knob == "edge_length" ? run_growth_study_case(which, v, 0.0, 0.0)
                             : knob == "dt"        ? run_growth_study_case(which, 0.0, v, 0.0)
                                                   : run_growth_study_case(which, 0.0, 0.0, v);
        run.knob = knob;
        run.value = v;
        if (progress) progress(run);
        runs.push_back(std::move(run));
      }
      const GrowthStudyRun& ref = runs.back();
      for (const GrowthStudyRun& run : runs) {
        double path = 0.0;
        const std::size_t n = std::min(run.tips.size(), ref.tips.size());
        for (std::size_t k = 0; k < n; ++k) path = std::max(path, (run.tips[k] - ref.tips[k]).norm());
        const double nan = std::numeric_limits<double>::quiet_NaN();
        const bool comparable = run.ok && ref.ok;
        csv += std::string(which == GrowthStudyCase::kY ? "y" : "carina") + "," + run.knob;
        for (const double x : {run.value, run.ok ? 1.0 : 0.0, run.grown, static_cast<double>(run.steps),
                               static_cast<double>(run.newton), run.seconds, run.peak_node_normal,
                               run.peak_total_normal,
                               comparable ? path : nan,
                               comparable ? std::abs(run.peak_node_normal / ref.peak_node_normal - 1.0) : nan,
                               comparable ? std::abs(run.peak_total_normal / ref.peak_total_normal - 1.0) : nan}) {
          csv += ',';
          append_number(csv, x);
        }
        csv += ",\"" + run.failure + "\"\n";
      }
    }
  }
  write_file_atomically(dir / "growth_study.csv", csv);
}

}  // namespace magvine::studies
