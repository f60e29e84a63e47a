#include "magvine/studies/design_study.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/units.hpp"

namespace magvine::studies {

design::DesignProblem thesis_catheter_problem() {
  design::DesignProblem p;
  // NdFeB–silicone as assets/scenes/rod_uniform_field.yaml (G 120 kPa, ρ 1882 kg/m³); the thesis names its MSCs'
  // material by reference only (appendix A.1.5, [12]).
  p.model = robot::circular_rod(0.040, 0.004, 120e3, 1882.0, 40);
  p.area = 0.25 * kPi * 0.004 * 0.004;
  const Vec3 b(0.0, 0.020, 0.0);
  p.field = robot::RodField([b](const Vec3&) { return magnetics::FieldSample{b, Mat3::Zero()}; });
  p.spec.sections = 5;
  p.spec.remanence = 0.125;
  for (int k = 0; k < 9; ++k) p.spec.target.emplace_back(0.005 * k, 0.0, 0.0);
  return p;
}

std::vector<Vec3> curve_target(double length, int points, const std::function<Vec3(double)>& curvature) {
  constexpr int kSteps = 4000;  // midpoint rotations: the points are exact to ~(L/kSteps)² relative
  const double ds = length / kSteps;
  Vec3 x = Vec3::Zero();
  Vec3 t = Vec3::UnitX();
  std::vector<Vec3> out{x};
  int next = 1;
  for (int i = 1; i <= kSteps; ++i) {
    const Vec3 k = curvature((i - 0.5) * ds);
    const Vec3 turn = t.cross(k - k.dot(t) * t) * ds;  // the rotation vector of this step
    x += ds * t;
    if (turn.norm() > 0.0) t = Eigen::AngleAxisd(turn.norm(), turn.normalized()) * t;
    if (i * (points - 1) == next * kSteps) {
      out.push_back(x);
      ++next;
    }
  }
  return out;
}

namespace {

void find_thresholds(DesignStudyRun& run) {
  for (const design::DesignResult::Step& s : run.result.history) {
    if (run.evaluations_to_2mm < 0 && s.best_rms <= 2e-3) {
      run.iterations_to_2mm = s.iteration;
      run.evaluations_to_2mm = s.evaluation;
      run.seconds_to_2mm = s.time_s;
    }
    if (run.evaluations_to_half_mm < 0 && s.best_rms <= 0.5e-3) {
      run.iterations_to_half_mm = s.iteration;
      run.evaluations_to_half_mm = s.evaluation;
      run.seconds_to_half_mm = s.time_s;
    }
  }
}

}  // namespace

std::vector<DesignStudyRun> run_design_study(const std::filesystem::path& out, int reachable,
                                             const std::function<void(const DesignStudyRun&)>& progress) {
  struct Target {
    std::string name;
    std::vector<Vec3> points;
    std::vector<std::uint64_t> starts;
  };
  std::vector<Target> targets;
  design::DesignProblem base = thesis_catheter_problem();
  for (int i = 1; i <= reachable; ++i) {
    design::DesignObjective o(base);
    const design::Design d = design::random_design(base, 100 + static_cast<std::uint64_t>(i));
    const robot::RodModel m = o.model_of(d);
    robot::RodState s = robot::straight_rod(m);
    if (!robot::solve_rod_statics(m, o.field_of(d), s, base.solver).converged) continue;
    targets.push_back({"reachable-" + std::to_string(100 + i), o.points_on(s), {static_cast<std::uint64_t>(i)}});
  }
  const double l = base.model.length;
  targets.push_back({"S",
                     curve_target(l, 9, [l](double s) { return Vec3(0, (s < l / 2 ? 1.0 : -1.0) * kPi / l, 0); }),
                     {1, 2, 3, 4}});
  targets.push_back(
      {"hook",
       curve_target(l, 9, [l](double s) { return s < l / 2 ? Vec3(0, kPi / l, 0) : Vec3(0, 0, kPi / l); }),
       {1, 2, 3, 4}});

  std::vector<DesignStudyRun> runs;
  std::ostringstream history;
  history.precision(9);
  history << "target,method,start_seed,iteration,evaluation,rms_m,best_rms_m,time_s\n";
  std::ostringstream shapes;
  shapes.precision(9);
  shapes << "target,start_seed,k,target_x,target_y,target_z,x,y,z\n";
  for (const Target& t : targets) {
    design::DesignProblem p = base;
    p.spec.target = t.points;
    for (const std::uint64_t seed : t.starts) {
      for (const char* method : {"least-squares", "lbfgsb", "bayesian"}) {
        design::DesignOptions options;
        options.seed = seed;
        DesignStudyRun run;
        run.target = t.name;
        run.method = method;
        run.start_seed = seed;
        const design::Design start = design::random_design(p, seed);
        const std::string m = method;
        run.result = m == "least-squares" ? design::least_squares_design(p, start, options)
                     : m == "lbfgsb"      ? design::optimise_design(p, start, options)
                                          : design::bayesian_design(p, options);
        find_thresholds(run);
        for (const design::DesignResult::Step& s : run.result.history) {
          history << t.name << ',' << method << ',' << seed << ',' << s.iteration << ',' << s.evaluation << ','
                  << (std::isfinite(s.rms) ? s.rms : -1.0) << ',' << s.best_rms << ',' << s.time_s << '\n';
        }
        if (m == "least-squares" && t.name.rfind("reachable", 0) != 0 && !run.result.state.x.empty()) {
          const design::DesignObjective o(p);
          const std::vector<Vec3> on = o.points_on(run.result.state);
          for (std::size_t k = 0; k < on.size(); ++k) {
            shapes << t.name << ',' << seed << ',' << k << ',' << t.points[k].x() << ',' << t.points[k].y() << ','
                   << t.points[k].z() << ',' << on[k].x() << ',' << on[k].y() << ',' << on[k].z() << '\n';
          }
        }
        if (progress) progress(run);
        runs.push_back(std::move(run));
      }
    }
  }
  std::ostringstream csv;
  csv.precision(9);
  csv << "target,method,start_seed,rms_m,max_error_m,iterations,evaluations,runtime_s,iterations_to_2mm,"
         "evaluations_to_2mm,seconds_to_2mm,iterations_to_0.5mm,evaluations_to_0.5mm,seconds_to_0.5mm\n";
  for (const DesignStudyRun& r : runs) {
    csv << r.target << ',' << r.method << ',' << r.start_seed << ',' << r.result.rms << ',' << r.result.max_error << ','
        << r.result.iterations << ',' << r.result.evaluations << ',' << r.result.runtime_s << ',' << r.iterations_to_2mm
        << ',' << r.evaluations_to_2mm << ',' << r.seconds_to_2mm << ',' << r.iterations_to_half_mm << ','
        << r.evaluations_to_half_mm << ',' << r.seconds_to_half_mm << '\n';
  }
  create_output_directory(out);
  write_file_atomically(out / "design_study.csv", csv.str());
  write_file_atomically(out / "design_history.csv", history.str());
  write_file_atomically(out / "design_shapes.csv", shapes.str());
  return runs;
}

}  // namespace magvine::studies
