// magvine: command-line entry point. Exit codes: 0 ok, 1 goal missed (where documented), 2 bad input,
// 3 numerical failure (DESIGN.md).

#include <CLI/CLI.hpp>
#include <iostream>

#include "commands.hpp"
#include "ct_command.hpp"
#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#include "mpm_command.hpp"
#include "phantom_command.hpp"
#include "render_command.hpp"

namespace {

std::string build_info() {
  std::string s = std::string("magvine ") + MAGVINE_VERSION +
                  " (render: " + (magvine::config::kWithRender ? "on" : "off") +
                  ", mpm: " + (magvine::config::kWithMpm ? "on" : "off") +
                  ", ct: " + (magvine::config::kWithCt ? "on" : "off") + ")";
  return s;
}

/// --slurm JOB.sh and its options (docs/cluster.md), for a verb whose `what` runs as shards.
void add_slurm_options(CLI::App& command, magvine::cli::SlurmOptions& slurm, const std::string& what) {
  command.add_option("--slurm", slurm.job,
                     "JOB.sh: write " + what +
                         " as a Slurm array of --shards tasks (JOB.sh) and the merge job (JOB.merge.sh) instead of "
                         "running");
  command.add_option("--shards", slurm.shards, "with --slurm: the array's tasks (shards; Slurm's default limit 1001)")
      ->check(CLI::Range(1, 1001));
  command.add_flag("--submit", slurm.submit, "with --slurm: submit both (sbatch, the merge afterok)");
  command.add_option("--partition", slurm.partition, "with --slurm: #SBATCH --partition");
  command.add_option("--time", slurm.time, "with --slurm: #SBATCH --time of each shard, e.g. 01:00:00");
  command.add_option("--mem", slurm.mem, "with --slurm: #SBATCH --mem of each shard, e.g. 4G");
}

}  // namespace

int main(int argc, char** argv) {
  using magvine::ExitCode;
  CLI::App app{"magvine: magnetically steered soft robots in anatomy"};
  app.set_version_flag("--version", build_info());
  app.require_subcommand(1);

  magvine::cli::FieldArgs field;
  auto* field_cmd = app.add_subcommand("field", "B and its gradient at points (SI CSV in, SI CSV out)");
  field_cmd->add_option("--magnets", field.magnets, "magnets file (YAML)")->required();
  field_cmd->add_option("--points", field.points, "CSV with header x,y,z in metres")->required();
  field_cmd->add_option("--out", field.out, "output CSV (default: stdout); written atomically");

  magvine::cli::FieldMapArgs map;
  auto* map_cmd =
      app.add_subcommand("field-map", "|B| and |grad B| on a plane (CSV + JSON for tools/plot_field_map.py)");
  map_cmd->add_option("--magnets", map.magnets, "magnets file (YAML)")->required();
  map_cmd->add_option("--plane", map.plane, "plane axes, e.g. xz (u = first, v = second)")->capture_default_str();
  map_cmd->add_option("--center", map.center, "centre x,y,z in --units")->capture_default_str();
  map_cmd->add_option("--extent", map.extent, "half-width of the square in --units")->capture_default_str();
  map_cmd->add_option("--units", map.units, "mm | cm | m")->capture_default_str();
  map_cmd->add_option("--resolution", map.resolution, "samples per side")->capture_default_str();
  map_cmd->add_option("--out", map.out_dir, "output folder (field_map.csv, field_map.json)")->required();

  magvine::cli::StudyArgs study;
  auto* study_cmd = app.add_subcommand("study", "convergence studies: error against runtime");
  study_cmd->require_subcommand(1);
  auto* study_fields = study_cmd->add_subcommand(
      "field-models", "exact cylinder vs dipole vs surface quadrature, against a fine quadrature (CSV)");
  study_fields->add_option("--magnets", study.magnets, "magnets file; its first cylinder is studied")->required();
  study_fields->add_option("--out", study.out_dir, "output folder")->required();
  std::string meshing_out;
  auto* study_meshing = study_cmd->add_subcommand(
      "phantom-meshing", "phantom meshing spacing: capsule vs closed form, bronchial tree vs finest (CSV)");
  study_meshing->add_option("--out", meshing_out, "output folder")->required();
  std::string centerline_out;
  auto* study_centerline = study_cmd->add_subcommand(
      "centerline", "airway-graph voxel size: the generated tree's extracted graph vs its ground truth (CSV)");
  study_centerline->add_option("--out", centerline_out, "output folder")->required();
  std::string growth_out;
  bool growth_quick = false;
  auto* study_growth = study_cmd->add_subcommand(
      "growth",
      "vine growth past the carina and into the Y: tip path and peak wall forces against edge length, dt "
      "and d-hat, each against its finest run (CSV; tools/plot_growth_study.py draws it)");
  study_growth->add_option("--out", growth_out, "output folder")->required();
  study_growth->add_flag("--quick", growth_quick, "two settings per knob (a check, not a study)");

  std::string design_study_out;
  int design_study_reachable = 8;
  auto* study_design = study_cmd->add_subcommand(
      "design",
      "computational design of thesis A.1.5.1's catheter: least-squares, L-BFGS-B and Bayesian optimisation "
      "on reachable and arbitrary targets, RMS against iterations and time (CSV; tools/plot_design_study.py)");
  study_design->add_option("--out", design_study_out, "output folder")->required();
  study_design->add_option("--reachable", design_study_reachable, "reachable targets (random designs' shapes)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));

  magvine::cli::MeshCheckArgs mesh_check;
  auto* mesh_cmd = app.add_subcommand("mesh", "anatomy mesh tools");
  mesh_cmd->require_subcommand(1);
  auto* mesh_check_cmd = mesh_cmd->add_subcommand(
      "check", "mesh diagnostics: counts, size, watertightness, genus, openings; exit 0 usable, 2 unusable");
  mesh_check_cmd->add_option("file", mesh_check.file, "mesh file (STL, OBJ, PLY, glTF/GLB, OFF, ...)")->required();
  mesh_check_cmd->add_option("--units", mesh_check.units, "unit of the file's coordinates: mm | cm | m")
      ->capture_default_str();
  mesh_check_cmd->add_flag("--json", mesh_check.json, "print the JSON report instead of the summary");
  magvine::cli::MeshGraphArgs mesh_graph;
  auto* mesh_graph_cmd = mesh_cmd->add_subcommand(
      "graph", "centreline graph of a closed airway mesh: branches named from the root, generations, radii (JSON)");
  mesh_graph_cmd->add_option("file", mesh_graph.file, "mesh file (STL, OBJ, PLY, glTF/GLB, OFF, ...)")->required();
  mesh_graph_cmd
      ->add_option("--units", mesh_graph.units,
                   "unit of the file's coordinates, --voxel and --root: "
                   "mm | cm | m")
      ->capture_default_str();
  mesh_graph_cmd->add_option("--voxel", mesh_graph.voxel, "voxel edge (default: auto, about 2 M lumen voxels)");
  mesh_graph_cmd->add_option("--root", mesh_graph.root, "X,Y,Z near the trachea's end (default: the widest end)")
      ->delimiter(',')
      ->expected(3);
  mesh_graph_cmd->add_option("--out", mesh_graph.out, "the graph (.json)")->required();
  mesh_graph_cmd->add_option("--png", mesh_graph.png, "also a picture of the graph over the mesh (.png)");
  mesh_check_cmd->add_option("--out", mesh_check.out, "also write the JSON report to this file");

  magvine::cli::RunArgs run;
  auto* run_cmd = app.add_subcommand("run",
                                     "one experiment: a free-space equilibrium (metrics.json, shape.csv) or, for "
                                     "a scene with anatomy:, growth under its control schedule (metrics, "
                                     "trajectories, events); exit 3 when it does not converge");
  run_cmd->add_option("scene", run.scene, "scene file (YAML)")->required();
  run_cmd->add_option("--out", run.out, "output folder (default: runs/<scene name>)");

  magvine::cli::TrialsArgs trials;
  auto* trials_cmd = app.add_subcommand(
      "trials",
      "repeated experiments with seeded perturbations (EPM placement, pressure, material), in parallel; a "
      "summary table like thesis table 5.2 (CSV + Markdown)");
  trials_cmd->add_option("scene", trials.scene, "experiment scene (YAML, with control.navigator for --targets)");
  trials_cmd->add_option("--targets", trials.targets, "branch names to aim the navigator at (default: the scene's)")
      ->delimiter(',');
  trials_cmd->add_option("--repeats", trials.repeats, "trials per target")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  trials_cmd->add_option("--jobs", trials.jobs, "threads (default: every core)")->check(CLI::Range(1, 1024));
  trials_cmd->add_option("--out", trials.out, "output folder (default: runs/<scene name>-trials)");
  trials_cmd->add_flag("--keep-runs", trials.keep_runs,
                       "also write each trial's outputs (metrics, events, trajectories; no videos) to "
                       "OUT/runs/<target>_r<repeat> (e.g. 0-1-0_r3)");
  trials_cmd->add_option("--shard", trials.shard,
                         "I/N: only the trials whose index is I mod N, each with its seed in the whole batch; writes "
                         "OUT/shard.json for `trials merge` (docs/cluster.md)");
  add_slurm_options(*trials_cmd, trials.slurm, "the batch");
  magvine::cli::TrialsMergeArgs merge;
  auto* merge_cmd = trials_cmd->add_subcommand(
      "merge", "join the shards of one batch (magvine trials --shard I/N) into trials.csv and the summary");
  merge_cmd->add_option("dirs", merge.dirs, "the shards' folders")->required();
  merge_cmd->add_option("--out", merge.out, "the merged batch's folder")->required();

  magvine::cli::DesignArgs design;
  auto* design_cmd = app.add_subcommand(
      "design",
      "computational design: the magnetisation sections (and a uniform field) that put a rod's equilibrium "
      "on a target shape (design.json, scene.yaml for magvine run; docs/design.md)");
  design_cmd->add_option("scene", design.scene, "design file: a free-space rod scene plus design:");
  design_cmd->add_option("--out", design.out, "output folder (default: runs/<file name>-design)");
  design_cmd->add_flag("--mpm-check", design.mpm_check,
                       "also simulate the design in 3D MPM (the thesis's method) and report the rod-MPM difference");
  design_cmd->add_option("--mpm-cell", design.mpm_cell_mm, "the MPM check's grid spacing [mm] (default: diameter/4)")
      ->check(CLI::Range(0.01, 100.0));
  design_cmd->add_option("--mpm-particles", design.mpm_particles, "the MPM check's particles per cell per axis")
      ->capture_default_str()
      ->check(CLI::Range(1, 8));
  design_cmd->add_option("--shard", design.shard,
                         "I/N: only the starts whose index is I mod N (each with its seed in the whole sweep); writes "
                         "OUT/shard.json for `design merge` (docs/cluster.md)");
  add_slurm_options(*design_cmd, design.slurm, "the starts");
  magvine::cli::DesignMergeArgs design_merge;
  auto* design_merge_cmd = design_cmd->add_subcommand(
      "merge", "join the shards of one design sweep (magvine design --shard I/N) into the design one machine finds");
  design_merge_cmd->add_option("dirs", design_merge.dirs, "the shards' folders")->required();
  design_merge_cmd->add_option("--out", design_merge.out, "the merged design's folder")->required();
  design_merge_cmd->add_option("--scene", design_merge.scene,
                               "the design file, when not where the shards ran it (its bytes must be theirs)");
  design_merge_cmd->add_flag("--mpm-check", design_merge.mpm_check, "also simulate the design in 3D MPM");
  design_merge_cmd->add_option("--mpm-cell", design_merge.mpm_cell_mm, "the MPM check's grid spacing [mm]")
      ->check(CLI::Range(0.01, 100.0));
  design_merge_cmd->add_option("--mpm-particles", design_merge.mpm_particles, "the MPM check's particles per cell")
      ->capture_default_str()
      ->check(CLI::Range(1, 8));

  magvine::cli::CalibrateArgs calibrate;
  auto* calibrate_cmd = app.add_subcommand(
      "calibrate",
      "fit uncertain parameters of a vine scene (film modulus, iron fraction, ...) to measured equilibria under an "
      "approaching magnet, with their uncertainty and held-out predictions (docs/design.md#calibration)");
  calibrate_cmd->add_option("scene", calibrate.scene, "calibration file: a free-space vine scene plus calibrate:")
      ->required();
  calibrate_cmd->add_option("--out", calibrate.out, "output folder (default: runs/<file name>-calibrate)");

  std::string validate_out;
  auto* validate_cmd = app.add_subcommand(
      "validate",
      "robot mechanics against the references: rod vs elastica (error against runtime), skin vine vs "
      "the two-stage model, magnetic-fluid vines vs EPM distance (CSV)");
  validate_cmd->add_option("--out", validate_out, "output folder")->required();

  magvine::cli::PhantomCommand phantom;
  phantom.attach(app);
  magvine::cli::MpmCommand mpm_cmd;
  mpm_cmd.attach(app, *study_cmd);
  magvine::cli::RenderCommand render_cmd;
  render_cmd.attach(app);
  magvine::cli::CtCommand ct_cmd;
  ct_cmd.attach(app, *study_cmd);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "magvine: " << e.what() << " (see magvine --help)\n";
    return static_cast<int>(ExitCode::kBadInput);
  }

  try {
    if (field_cmd->parsed()) return magvine::cli::run_field(field);
    if (map_cmd->parsed()) return magvine::cli::run_field_map(map);
    if (study_fields->parsed()) return magvine::cli::run_study_field_models(study);
    if (study_meshing->parsed()) return magvine::cli::run_study_phantom_meshing(meshing_out);
    if (study_growth->parsed()) return magvine::cli::run_study_growth(growth_out, growth_quick);
    if (study_design->parsed()) return magvine::cli::run_study_design(design_study_out, design_study_reachable);
    if (study_centerline->parsed()) return magvine::cli::run_study_centerline(centerline_out);
    if (mesh_check_cmd->parsed()) return magvine::cli::run_mesh_check(mesh_check);
    if (mesh_graph_cmd->parsed()) return magvine::cli::run_mesh_graph(mesh_graph);
    if (phantom.parsed()) return phantom.run();
    if (mpm_cmd.parsed()) return mpm_cmd.run();
    if (render_cmd.parsed()) return render_cmd.run();
    if (ct_cmd.parsed()) return ct_cmd.run();
    if (run_cmd->parsed()) return magvine::cli::run_scene(run);
    if (validate_cmd->parsed()) return magvine::cli::run_validate(validate_out);
    if (merge_cmd->parsed()) {
      // `magvine trials merge` takes the shards' folders and --out only: anything given to trials itself is a slip.
      const auto given = trials_cmd->get_options([](const CLI::Option* o) { return o->count() > 0; });
      if (!given.empty()) {
        throw magvine::InputError(
            "trials merge", 0, "",
            "takes the shards' folders and --out only (give the scene and options to the shards)");
      }
      return magvine::cli::run_trials_merge(merge);
    }
    if (trials_cmd->parsed()) {
      if (trials.scene.empty()) throw magvine::InputError("trials", 0, "", "name the scene: magvine trials SCENE");
      return magvine::cli::run_trials(trials);
    }
    if (design_merge_cmd->parsed()) {
      const auto given = design_cmd->get_options([](const CLI::Option* o) { return o->count() > 0; });
      if (!given.empty()) {
        throw magvine::InputError("design merge", 0, "",
                                  "takes the shards' folders, --out and the MPM check's options only (give the scene "
                                  "and options to the shards)");
      }
      return magvine::cli::run_design_merge(design_merge);
    }
    if (design_cmd->parsed()) {
      if (design.scene.empty()) throw magvine::InputError("design", 0, "", "name the design file: magvine design FILE");
      return magvine::cli::run_design(design);
    }
    if (calibrate_cmd->parsed()) return magvine::cli::run_calibrate(calibrate);
  } catch (const magvine::InputError& e) {
    std::cerr << "magvine: " << e.what() << '\n';
    return static_cast<int>(ExitCode::kBadInput);
  } catch (const magvine::NumericalError& e) {
    std::cerr << "magvine: numerical failure: " << e.what() << '\n';
    return static_cast<int>(ExitCode::kNumericalFailure);
  } catch (const std::exception& e) {
    std::cerr << "magvine: internal error: " << e.what() << '\n';
    return 4;
  }
  return 0;
}
