#include "commands.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <thread>

#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/config.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_model.hpp"
#include "magvine/scene/calibrate_scene.hpp"
#include "magvine/scene/design_scene.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/field_map.hpp"
#include "magvine/scene/trials.hpp"
#include "magvine/studies/centerline_study.hpp"
#include "magvine/studies/design_study.hpp"
#include "magvine/studies/field_study.hpp"
#include "magvine/studies/growth_study.hpp"
#if MAGVINE_WITH_MPM
#include "magvine/scene/mpm_scene.hpp"
#endif
#include "magvine/scene/free_space.hpp"
#include "magvine/scene/magnets_file.hpp"
#include "magvine/scene/points_csv.hpp"
#include "magvine/scene/video_plugin.hpp"
#include "magvine/studies/mechanics_study.hpp"
#include "magvine/studies/meshing_study.hpp"

namespace magvine::cli {

int run_field(const FieldArgs& args) {
  const magnetics::FieldModel model = scene::load_magnets_file(args.magnets);
  const std::vector<Vec3> points = scene::read_points_csv(args.points);
  std::vector<magnetics::FieldSample> samples(points.size());
  magnetics::field_gradient_batch(model, model.rest_poses, points, samples);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    // The field models are finite everywhere by construction; a non-finite value here is a bug, not input.
    if (!samples[i].b.allFinite() || !samples[i].g.allFinite()) {
      throw NumericalError("field: non-finite result at point " + std::to_string(i + 1));
    }
  }
  if (args.out.empty()) {
    scene::write_field_csv(std::cout, points, samples);
  } else {
    AtomicFile out(args.out);
    scene::write_field_csv(out.stream(), points, samples);
    out.commit();
    std::cerr << "magvine field: " << points.size() << " points -> " << args.out << '\n';
  }
  return 0;
}

int run_field_map(const FieldMapArgs& args) {
  const double s = metres_per(parse_units_option(args.units));
  scene::FieldMapSpec spec;
  spec.plane = args.plane;
  spec.half_width = args.extent * s;
  spec.resolution = args.resolution;
  {
    const InputError bad("--center", 0, "", "must be three numbers x,y,z (got '" + args.center + "')");
    std::stringstream ss(args.center);
    std::string item;
    int i = 0;
    while (std::getline(ss, item, ',')) {
      if (i >= 3) throw bad;
      try {
        std::size_t used = 0;
        spec.center[i] = std::stod(item, &used) * s;
        if (used != item.size() || !std::isfinite(spec.center[i])) throw bad;
      } catch (const std::logic_error&) {  // std::stod: invalid_argument, out_of_range
        throw bad;
      }
      ++i;
    }
    if (i != 3) throw bad;
  }
  const magnetics::FieldModel model = scene::load_magnets_file(args.magnets);
  const std::filesystem::path dir(args.out_dir);
  const auto csv = dir / "field_map.csv";
  const auto json = dir / "field_map.json";
  scene::write_field_map(model, spec, csv, json);
  std::cerr << "magvine field-map: " << spec.resolution << "x" << spec.resolution << " samples in plane " << spec.plane
            << " -> " << csv.string() << ", " << json.string() << '\n';
  return 0;
}

int run_study_field_models(const StudyArgs& args) {
  const magnetics::FieldModel model = scene::load_magnets_file(args.magnets);
  const magnetics::CylinderMagnet* magnet = nullptr;
  for (const auto& s : model.sources) {
    if ((magnet = std::get_if<magnetics::CylinderMagnet>(&s))) break;
  }
  if (!magnet) throw InputError(args.magnets, 0, "magnets", "contains no cylinder (with model: exact) to study");
  create_output_directory(args.out_dir);
  studies::run_field_model_study(*magnet, studies::FieldStudySpec{}, args.out_dir);
  std::cerr << "magvine study field-models: " << args.out_dir << "/field_models.csv, " << args.out_dir
            << "/field_model_distance.csv\n";
  return 0;
}

int run_study_phantom_meshing(const std::string& out_dir) {
  create_output_directory(out_dir);
  studies::run_meshing_study(out_dir);
  std::cerr << "magvine study phantom-meshing: " << out_dir << "/meshing_study.csv\n";
  return 0;
}

int run_study_centerline(const std::string& out_dir) {
  create_output_directory(out_dir);
  studies::run_centerline_study(out_dir);
  std::cerr << "magvine study centerline: " << out_dir << "/centerline_study.csv\n";
  return 0;
}

int run_study_growth(const std::string& out_dir, bool quick) {
  create_output_directory(out_dir);
  studies::run_growth_study(out_dir, quick, [](const studies::GrowthStudyRun& r) {
    std::cerr << printf_string(
        "  %-6s %-16s %8.4g  %s  %6.1f mm grown  %5d steps  %6d Newton  %7.2f s  "
        "peak node %.3f N, total %.3f N\n",
        r.which == studies::GrowthStudyCase::kY ? "y" : "carina", r.knob.c_str(),
        r.knob == "dt" ? r.value : 1e3 * r.value, r.ok ? "ok    " : "FAILED", 1e3 * r.grown, r.steps, r.newton,
        r.seconds, r.peak_node_normal, r.peak_total_normal);
  });
  std::cerr << "magvine study growth: " << out_dir << "/growth_study.csv (tools/plot_growth_study.py " << out_dir
            << ")\n";
  return 0;
}

int run_study_design(const std::string& out_dir, int reachable) {
  studies::run_design_study(out_dir, reachable, [](const studies::DesignStudyRun& r) {
    std::cerr << printf_string(
        "  %-14s %-13s start %d: RMS %7.3f mm, %4d iterations, %4d evaluations, %6.3f s; "
        "2 mm after %d evaluations, 0.5 mm after %d\n",
        r.target.c_str(), r.method.c_str(), static_cast<int>(r.start_seed), r.result.rms * 1e3, r.result.iterations,
        r.result.evaluations, r.result.runtime_s, r.evaluations_to_2mm, r.evaluations_to_half_mm);
  });
  std::cerr << "magvine study design: " << out_dir << "/design_study.csv, design_history.csv, design_shapes.csv "
            << "(tools/plot_design_study.py " << out_dir << ")\n";
  return 0;
}

LengthUnit parse_units_option(const std::string& text) {
  const auto unit = parse_length_unit(text);
  if (!unit) throw InputError("--units", 0, "", "must be mm, cm or m (got '" + text + "')");
  return *unit;
}

int run_mesh_check(const MeshCheckArgs& args) {
  const LengthUnit units = parse_units_option(args.units);
  const anatomy::ImportedMesh imported = anatomy::import_mesh(args.file, {.units = units});
  const anatomy::MeshReport report = anatomy::analyse_mesh(imported.mesh);
  const std::string json = anatomy::report_json(args.file, imported, report, units);
  if (!args.out.empty()) write_file_atomically(args.out, json);
  std::cout << (args.json ? json : anatomy::report_summary(args.file, imported, report));
  return 0;
}

int run_mesh_graph(const MeshGraphArgs& args) {
  const LengthUnit units = parse_units_option(args.units);
  const double unit = metres_per(units);
  if (std::filesystem::path(args.out).extension() != ".json") {
    throw InputError("--out", 0, "", args.out + " is not a .json path");
  }
  if (!args.png.empty() && std::filesystem::path(args.png).extension() != ".png") {
    throw InputError("--png", 0, "", args.png + " is not a .png path");
  }
  // Loaded before the work starts: a missing render module is an input error, with nothing written.
  const scene::VideoPlugin* plugin = args.png.empty() ? nullptr : &scene::video_plugin("--png");
  if (!(args.voxel >= 0.0 && std::isfinite(args.voxel))) throw InputError("--voxel", 0, "", "must be a length > 0");
  anatomy::CenterlineOptions options;
  options.voxel = args.voxel * unit;
  if (!args.root.empty()) options.root = Vec3(args.root[0], args.root[1], args.root[2]) * unit;
  const anatomy::ImportedMesh imported = anatomy::import_mesh(args.file, {.units = units});
  anatomy::CenterlineReport report;
  const anatomy::AirwayGraph graph = anatomy::extract_airway_graph(imported.mesh, options, &report);
  const std::string picture = plugin != nullptr ? plugin->graph_picture(imported.mesh, graph).png : std::string();
  anatomy::write_graph(args.out, graph);
  if (plugin != nullptr) write_file_atomically(args.png, picture);
  int deepest = 0;
  for (const auto& b : graph.branches) deepest = std::max(deepest, b.generation);
  std::cout << args.file << ": " << graph.branches.size() << " branches, " << anatomy::leaves(graph).size()
            << " leaves, generations 0-" << deepest << "; voxel " << report.voxel / unit << " " << args.units << " ("
            << report.dims[0] << " x " << report.dims[1] << " x " << report.dims[2] << ", " << report.inside_voxels
            << " in the lumen, " << report.components
            << (report.components == 1 ? " component" : " components, the largest kept") << "), " << report.spurs_pruned
            << " spurs pruned, " << report.seconds << " s -> " << args.out << (args.png.empty() ? "" : " + " + args.png)
            << "\n";
  return 0;
}

int failed_run(const std::string& cause, const std::filesystem::path& out) {
  std::cerr << "magvine: numerical failure: " << cause << " (" << (out / "metrics.json").string()
            << " says why; no other file is written)\n";
  return static_cast<int>(ExitCode::kNumericalFailure);
}

void preload_videos(bool wanted, const std::string& scene, const std::string& what) {
  if (wanted && !scene::preload_video_plugin(wanted, scene + ": " + what)) {
    std::cerr << "magvine: warning: " << scene << ": " << what
              << " skipped: this magvine was built without the render module\n";
  }
}

std::function<void(double)> progress_bar() {
  return [shown = -1](double done) mutable {
    const int percent = static_cast<int>(100.0 * done);
    if (percent / 10 == shown) return;
    shown = percent / 10;
    std::cerr << "\r  [" << std::string(static_cast<std::size_t>(shown), '#')
              << std::string(static_cast<std::size_t>(10 - shown), '.') << "] " << percent << " %" << std::flush;
  };
}

int run_experiment_scene(const RunArgs& args, const std::filesystem::path& out) {
  const scene::ExperimentScene sc = scene::load_experiment_scene(args.scene);
  const bool rod = sc.growth.rod.has_value();
  std::cerr << "magvine run: " << (rod ? "pushing a rod into " : "growing a vine in ") << sc.anatomy->label << " for "
            << sc.duration << " s (" << sc.anatomy->mesh().triangles.size() << " triangles)\n";
  preload_videos(!sc.videos.empty(), args.scene, "outputs.video");
  const scene::ExperimentResult result = scene::run_experiment(sc, progress_bar());
  std::cerr << '\n';
  if (!sc.videos.empty() && result.converged) {
    std::cerr << "magvine run: rendering " << sc.videos.size() << (sc.videos.size() == 1 ? " video" : " videos")
              << " of " << result.frames.size() << " frames\n";
  }
  scene::write_experiment_outputs(sc, result, out);
  // A contact pressure far above the film's is load a film at that pressure could not carry: the contact's rigid
  // sphere carried it (a wedged node, or a vine deflated under a load). Say so, so that its wall forces are read
  // with that in mind. The threshold, 2: the bundled phantom scenes read exactly 1; in the CT biopsy studies 21 runs
  // peaked between 0.97 and 1.62 times the nominal pressure, and every needle held came at 2.5 times or more.
  if (const std::optional<double> overload = scene::film_overload(sc, result); overload && *overload > 2.0) {
    std::cerr << "magvine: warning: " << args.scene << ": a node pressed the wall at "
              << printf_string("%.1f", *overload)
              << " times the vine's pressure at that step, more than its film can: the contact's rigid sphere "
                 "carried it (a wedged node, or a deflated vine under load; docs/growth-and-contact.md, Known gaps)\n";
  }
  if (!result.converged) return failed_run(result.failure, out);
  const Vec3 tip = result.final_state.tip() / kMmToM;
  std::cerr << "magvine run: " << result.samples.back().length / kMmToM << (rod ? " mm inserted" : " mm everted")
            << ", tip at (" << tip.x() << ", " << tip.y() << ", " << tip.z() << ") mm, " << result.events.size()
            << " events"
            << (sc.target ? (result.success ? ", target reached at " + std::to_string(result.time_to_target) + " s"
                                            : std::string(", target not reached"))
                          : std::string())
            << (result.recoveries > 0 ? ", after " + std::to_string(result.recoveries) +
                                            (result.recoveries == 1 ? " retraction" : " retractions")
                                      : std::string())
            << "; " << result.runtime_s << " s of computing -> " << out.string() << "/{metrics.json,tip_trajectory.csv,"
            << (sc.magnets ? "magnet_trajectory.csv," : "") << "events.json,shape.csv"
            << (sc.videos.empty() ? "" : ",videos (metrics.json: videos)") << "}\n";
  return 0;
}

int run_scene(const RunArgs& args) {
  const std::filesystem::path out = args.out.empty()
                                        ? std::filesystem::path("runs") / std::filesystem::path(args.scene).stem()
                                        : std::filesystem::path(args.out);
#if MAGVINE_WITH_MPM
  if (scene::is_mpm_scene(args.scene)) {
    throw InputError(args.scene + ": an MPM scene (it has mpm:); run it with magvine mpm " + args.scene);
  }
#endif
  if (scene::is_experiment_scene(args.scene)) return run_experiment_scene(args, out);
  const scene::FreeSpaceScene sc = scene::load_free_space_scene(args.scene);
  const scene::FreeSpaceResult result = scene::solve_free_space(sc);
  scene::write_free_space_outputs(sc, result, out);
  if (!result.report.converged) return failed_run("static equilibrium: " + result.report.failure, out);
  const Vec3 tip = result.state.tip() / kMmToM;
  std::cerr << "magvine run: " << sc.kind() << ", " << sc.model.edges + 1 << " nodes, converged in "
            << result.report.iterations << " Newton iterations (" << result.runtime_s * 1e3 << " ms); tip at ("
            << tip.x() << ", " << tip.y() << ", " << tip.z() << ") mm -> " << (out / "metrics.json").string() << ", "
            << (out / "shape.csv").string() << '\n';
  return 0;
}

namespace {

/// --shards, --submit, --partition, --time and --mem belong to --slurm, and --slurm writes every shard.
void check_slurm_options(const SlurmOptions& slurm, const std::string& shard) {
  if (slurm.job.empty() &&
      (slurm.shards > 0 || slurm.submit || !slurm.partition.empty() || !slurm.time.empty() || !slurm.mem.empty())) {
    throw InputError("--shards", 0, "", "--shards, --submit, --partition, --time and --mem go with --slurm JOB.sh");
  }
  if (!slurm.job.empty() && !shard.empty()) {
    throw InputError("--shard", 0, "", "--slurm writes every shard's task: leave --shard out");
  }
}

/// The default output folder: runs/<scene stem>-<suffix>.
std::string default_out(const std::string& scene, const char* suffix) {
  return (std::filesystem::path("runs") / (std::filesystem::path(scene).stem().string() + "-" + suffix)).string();
}

}  // namespace

int run_trials(const TrialsArgs& args) {
  check_slurm_options(args.slurm, args.shard);
  if (!args.slurm.job.empty()) {
    // What a shard would trip over fails here, before anything is written or queued.
    const scene::ExperimentScene sc = scene::load_experiment_scene(args.scene);
    for (const std::string& t : args.targets) (void)scene::with_target(sc, t);
    SlurmBatch b;
    b.verb = "trials";
    b.scene = args.scene;
    b.out = args.out.empty() ? default_out(args.scene, "trials") : args.out;
    b.slurm = args.slurm;
    std::string targets;
    for (const std::string& t : args.targets) targets += (targets.empty() ? "" : ",") + t;
    b.cpus = args.jobs > 0 ? args.jobs : 1;
    b.options = " --repeats " + std::to_string(args.repeats) +
                (targets.empty() ? "" : " --targets " + shell_word(targets)) + " --jobs " + std::to_string(b.cpus) +
                (args.keep_runs ? " --keep-runs" : "");
    return write_slurm_jobs(b);
  }
  const scene::Shard shard = args.shard.empty() ? scene::Shard{} : scene::parse_shard(args.shard);
  // The batch's identity from the scene's bytes as the shard starts (an edit during a long run is another batch).
  const scene::BatchIdentity identity = scene::batch_identity(args.scene, args.targets, args.repeats, shard);
  const scene::ExperimentScene sc = scene::load_experiment_scene(args.scene);
  const std::filesystem::path out = args.out.empty() ? default_out(args.scene, "trials") : args.out;
  const int jobs = args.jobs > 0 ? args.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const std::string& t : args.targets) (void)scene::with_target(sc, t);  // bad names fail before any output
  const std::size_t targets = args.targets.empty() ? 1 : args.targets.size();
  const std::size_t batch = targets * static_cast<std::size_t>(args.repeats);
  const std::size_t runs = scene::shard_items(batch, shard).size();
  std::cerr << "magvine trials: " << runs << " runs (" << targets << " target(s) x " << args.repeats << " repeats"
            << (args.shard.empty() ? std::string() : ", shard " + args.shard) << ") on " << jobs << " thread(s)\n";
  const std::vector<scene::TrialOutcome> outcomes = scene::run_trials(
      sc, args.targets, args.repeats, jobs,
      [](int done, int total) {
        const int bar = 20 * done / total;
        std::cerr << "\r  [" << std::string(static_cast<std::size_t>(bar), '#')
                  << std::string(static_cast<std::size_t>(20 - bar), '.') << "] " << done << "/" << total << std::flush;
      },
      args.keep_runs ? out / "runs" : std::filesystem::path(), shard);
  std::cerr << '\n';
  if (!args.shard.empty()) {
    scene::write_shard(identity, outcomes, out);
    std::cerr << "magvine trials: shard " << args.shard << ": " << (out / "shard.json").string() << ", "
              << (out / "trials.csv").string() << " (magvine trials merge joins the shards)\n";
    return 0;
  }
  scene::write_trial_outputs(outcomes, out);
  std::ifstream md(out / "summary.md");
  std::cout << md.rdbuf();
  std::cerr << "magvine trials: " << (out / "trials.csv").string() << ", " << (out / "summary.csv").string() << ", "
            << (out / "summary.md").string();
  if (args.keep_runs) std::cerr << ", each trial's outputs in " << (out / "runs").string() << "/<target>_r<repeat>";
  std::cerr << '\n';
  return 0;
}

namespace {

/// What --mpm-check refuses (no MPM module; an oblique base, a section that is not round, a gradient field), before any
/// design is run.
void check_mpm_check(const scene::DesignScene& sc, bool mpm_check, double cell_mm, int particles) {
  if (!mpm_check) return;
  if (!config::kWithMpm) {
    throw InputError(
        "--mpm-check: this magvine was built without the MPM module (configure with -DMAGVINE_WITH_MPM=ON)");
  }
  (void)scene::design_mpm_scene_yaml(sc, design::random_design(sc.problem, sc.seed), cell_mm * 1e-3, particles);
}

/// A design's outputs (and its MPM check), and its report: what `magvine design` and `magvine design merge` end with.
int finish_design(const scene::DesignScene& sc, const design::DesignResult& r, const std::filesystem::path& out,
                  bool mpm_check, double cell_mm, int particles) {
  if (!std::isfinite(r.rms)) {
    throw NumericalError("design " + sc.file + ": no design had a stable equilibrium (" + r.message + ")");
  }
  if (mpm_check) scene::check_design_mpm_scene(sc, r.design, cell_mm * 1e-3, particles);
  scene::write_design_outputs(sc, r, out);
  if (mpm_check) {
    std::cerr << "magvine design: the MPM check\n";
    const scene::DesignMpmCheck m = scene::run_design_mpm_check(sc, r, out, cell_mm * 1e-3, particles, [](double f) {
      std::cerr << "\r  " << static_cast<int>(100.0 * f) << " %   " << std::flush;
    });
    std::cerr << '\n';
    scene::add_mpm_check_to_design_json(m, out);
    std::cout << printf_string(
        "MPM check: rod-MPM RMS %.3f mm (largest %.3f mm), MPM-target RMS %.3f mm; %ld particles, "
        "%.2f s simulated (%s) in %.1f s%s\n",
        m.rms * 1e3, m.max * 1e3, m.target_rms * 1e3, m.particles, m.simulated_s, m.settled ? "settled" : "not settled",
        m.runtime_s, m.failure.empty() ? "" : (": " + m.failure).c_str());
  }
  std::cout << printf_string("RMS %.3f mm, largest error %.3f mm after %d iterations (%d equilibria) in %.2f s: %s\n",
                             r.rms * 1e3, r.max_error * 1e3, r.iterations, r.evaluations, r.runtime_s,
                             r.message.c_str());
  std::cerr << "magvine design: " << (out / "design.json").string() << ", " << (out / "scene.yaml").string()
            << " (magvine run reproduces the shape), shape.csv, target.csv\n";
  return 0;
}

}  // namespace

int run_design(const DesignArgs& args) {
  check_slurm_options(args.slurm, args.shard);
  const scene::Shard shard = args.shard.empty() ? scene::Shard{} : scene::parse_shard(args.shard);
  if (!args.shard.empty() && args.mpm_check) {
    throw InputError("--mpm-check", 0, "", "give it to `magvine design merge`, not to a shard");
  }
  // The sweep's identity from the file's bytes as the shard starts (an edit during a long run is another sweep).
  const std::uint64_t fingerprint = args.shard.empty() ? 0 : scene::scene_fingerprint(args.scene);
  const scene::DesignScene sc = scene::load_design_scene(args.scene);  // bad input fails before any output
  check_mpm_check(sc, args.mpm_check, args.mpm_cell_mm, args.mpm_particles);
  const std::filesystem::path out = args.out.empty() ? default_out(args.scene, "design") : args.out;
  if (!args.slurm.job.empty() || !args.shard.empty()) {
    if (sc.method == scene::DesignMethod::bayesian) {
      throw InputError(args.scene, 0, "design.method",
                       "the Bayesian baseline is one run with its own initial designs: it has no starts to shard");
    }
  }
  if (!args.slurm.job.empty()) {
    if (args.slurm.shards > std::max(1, sc.starts)) {
      throw InputError("--shards", 0, "",
                       printf_string("%d shards for %d starts (design.starts) would leave tasks idle",
                                     args.slurm.shards, std::max(1, sc.starts)));
    }
    SlurmBatch b;
    b.verb = "design";
    b.scene = args.scene;
    b.out = out.string();
    b.slurm = args.slurm;
    if (args.mpm_check) {
      b.merge_options = printf_string(" --mpm-check --mpm-particles %d", args.mpm_particles) +
                        (args.mpm_cell_mm > 0.0 ? printf_string(" --mpm-cell %.17g", args.mpm_cell_mm) : "");
    }
    return write_slurm_jobs(b);
  }
  const char* method = sc.method == scene::DesignMethod::least_squares ? "Levenberg-Marquardt, exact Jacobian"
                       : sc.method == scene::DesignMethod::lbfgsb      ? "L-BFGS-B, exact adjoint gradient"
                                                                       : "Bayesian optimisation (derivative-free)";
  std::cerr << "magvine design: " << sc.problem.spec.sections << " sections, " << sc.problem.spec.target.size()
            << " target points, " << method << '\n';
  if (!args.shard.empty()) {
    const std::size_t mine = scene::shard_items(static_cast<std::size_t>(std::max(1, sc.starts)), shard).size();
    std::cerr << "  shard " << args.shard << ": " << mine << " of " << std::max(1, sc.starts) << " starts\n";
    const auto starts = scene::run_design_shard(sc, shard, [](int done, int total) {
      std::cerr << "\r  start " << done << "/" << total << " done   " << std::flush;
    });
    std::cerr << '\n';
    scene::write_design_shard(args.scene, fingerprint, sc, shard, starts, out);
    for (const auto& [start, r] : starts) {
      std::cout << printf_string("start %d: RMS %.3f mm after %d iterations (%d equilibria) in %.2f s\n", start,
                                 r.rms * 1e3, r.iterations, r.evaluations, r.runtime_s);
    }
    std::cerr << "magvine design: shard " << args.shard << ": " << (out / "shard.json").string()
              << " (magvine design merge joins the shards)\n";
    return 0;
  }
  const design::DesignResult r = scene::run_design(sc, [](int evaluations, double rms) {
    std::cerr << "\r  evaluation " << evaluations << ": best RMS " << printf_string("%.3f", rms * 1e3) << " mm   "
              << std::flush;
  });
  std::cerr << '\n';
  return finish_design(sc, r, out, args.mpm_check, args.mpm_cell_mm, args.mpm_particles);
}

int run_design_merge(const DesignMergeArgs& args) {
  if (args.out.empty()) throw InputError("--out", 0, "", "name the folder for the merged design");
  const std::vector<std::filesystem::path> dirs(args.dirs.begin(), args.dirs.end());
  const scene::MergedDesign m = scene::merge_design_shards(dirs, args.scene);
  check_mpm_check(m.scene, args.mpm_check, args.mpm_cell_mm, args.mpm_particles);
  std::cerr << "magvine design merge: " << dirs.size() << " shards, " << std::max(1, m.scene.starts) << " starts of "
            << m.scene.file << '\n';
  return finish_design(m.scene, m.result, args.out, args.mpm_check, args.mpm_cell_mm, args.mpm_particles);
}

int run_calibrate(const CalibrateArgs& args) {
  const scene::CalibrateScene sc = scene::load_calibrate_scene(args.scene);  // bad input fails before any output
  const std::filesystem::path out =
      args.out.empty()
          ? std::filesystem::path("runs") / (std::filesystem::path(args.scene).stem().string() + "-calibrate")
          : std::filesystem::path(args.out);
  int fitted = 0;
  for (const design::Measurement& m : sc.problem.measurements) fitted += m.holdout ? 0 : 1;
  std::cerr << "magvine calibrate: " << sc.problem.parameters.size() << " parameters, " << fitted
            << " measurements fitted, " << sc.problem.measurements.size() - static_cast<std::size_t>(fitted)
            << " held out, " << sc.problem.cases.size() << " cases (Levenberg-Marquardt, exact sensitivities)\n";
  design::CalibrationOptions options;
  options.max_iterations = sc.max_iterations;
  options.progress = [](int iteration, double chi) {
    std::cerr << "\r  iteration " << iteration << ": chi " << printf_string("%.4g", chi) << "   " << std::flush;
  };
  const design::CalibrationResult r = design::calibrate(sc.problem, options);
  std::cerr << '\n';
  scene::write_calibration_outputs(sc, r, out);
  for (std::size_t i = 0; i < sc.keys.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    const double unit = sc.keys[i].second;
    std::cout << printf_string("robot.%s = %.6g ± %.3g %s\n", sc.keys[i].first.c_str(), r.theta[k] / unit,
                               r.sigma[k] / unit, sc.unit_names[i].c_str());
  }
  std::cout << printf_string(
      "chi2 %.4g over %d fitted measurements after %d iterations (%d equilibria) in %.2f s: %s\n", r.chi2, r.fitted,
      r.iterations, r.equilibria, r.runtime_s, r.message.c_str());
  std::cerr << "magvine calibrate: " << (out / "calibration.json").string() << ", "
            << (out / "predictions.csv").string() << " (held-out predictions with z-scores), "
            << (out / "scene.yaml").string() << "\n";
  return 0;
}

int run_validate(const std::string& out_dir) {
  create_output_directory(out_dir);
  std::cerr << "magvine validate: rod against the elastica (error against runtime)\n";
  studies::run_rod_convergence_study(out_dir);
  std::cerr << "magvine validate: skin MVR against the two-stage model\n";
  studies::run_vine_deflection_study(out_dir);
  std::cerr << "magvine validate: magnetic-fluid vines against EPM distance\n";
  studies::run_fluid_vine_study(out_dir);
  std::cerr << "magvine validate: " << out_dir << "/{rod_convergence,vine_deflection,fluid_vine,fluid_vine_summary}.csv"
            << " (plots: tools/plot_mechanics.py " << out_dir << ")\n";
  return 0;
}

}  // namespace magvine::cli
