#pragma once
// The verbs of the magvine executable. Each returns the process exit code and throws InputError for bad input.

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/core/units.hpp"

namespace magvine::cli {

/// Parses a --units value (mm | cm | m); InputError naming the option otherwise.
LengthUnit parse_units_option(const std::string& text);

struct FieldArgs {
  std::string magnets;
  std::string points;
  std::string out;  // empty: stdout
};
int run_field(const FieldArgs& args);

struct FieldMapArgs {
  std::string magnets;
  std::string plane = "xz";
  std::string units = "mm";
  std::string center = "0,0,0";
  double extent = 300.0;  // half-width, in `units`
  int resolution = 201;
  std::string out_dir;
};
int run_field_map(const FieldMapArgs& args);

struct StudyArgs {
  std::string magnets;  // the first cylinder in it is studied
  std::string out_dir;
};
int run_study_field_models(const StudyArgs& args);
int run_study_phantom_meshing(const std::string& out_dir);

struct MeshCheckArgs {
  std::string file;
  std::string units = "mm";
  bool json = false;  // JSON on stdout instead of the summary
  std::string out;    // also write the JSON report here (atomically)
};
int run_mesh_check(const MeshCheckArgs& args);

struct MeshGraphArgs {
  std::string file;
  std::string units = "mm";
  double voxel = 0.0;        // in --units; 0: auto
  std::vector<double> root;  // X,Y,Z in --units; empty: the widest end
  std::string out;           // graph.json
  std::string png;           // the graph over the mesh (render module)
};
int run_mesh_graph(const MeshGraphArgs& args);
int run_study_centerline(const std::string& out_dir);
int run_study_growth(const std::string& out_dir, bool quick);
int run_study_design(const std::string& out_dir, int reachable);

struct RunArgs {
  std::string scene;
  std::string out;  // empty: runs/<scene stem>
};
/// One free-space equilibrium (issue 4's scene): 0 converged, 3 not (outputs written with converged: false).
int run_scene(const RunArgs& args);

/// --slurm JOB.sh: write a batch as a Slurm array of `shards` shards and its merge job instead of running it
/// (docs/cluster.md); --submit also submits both with sbatch. Resources as sbatch takes them.
struct SlurmOptions {
  std::string job;  ///< JOB.sh; empty: run here
  int shards = 0;
  bool submit = false;
  std::string partition;
  std::string time;  ///< each task's time limit
  std::string mem;   ///< memory per task
};

struct TrialsArgs {
  std::string scene;
  std::vector<std::string> targets;  // branch names; empty: the scene's own target
  int repeats = 4;
  int jobs = 0;            // 0: every core
  std::string out;         // empty: runs/<scene stem>-trials
  bool keep_runs = false;  // each trial's outputs in <out>/runs/<target>_r<repeat>
  std::string shard;       // "I/N": only that shard's trials (docs/cluster.md); empty: all
  SlurmOptions slurm;
};
/// `magvine trials`: seeded perturbed repeats of an experiment towards each target, in parallel (scene/experiment.hpp);
/// with --shard one share of them, with --slurm the batch as Slurm jobs (cluster.cpp).
int run_trials(const TrialsArgs& args);

struct TrialsMergeArgs {
  std::vector<std::string> dirs;
  std::string out;
};
/// `magvine trials merge DIR... --out DIR`: the shards' batch as one machine writes it (docs/cluster.md).
int run_trials_merge(const TrialsMergeArgs& args);

/// A sharded batch as Slurm jobs (cluster.cpp): `magvine VERB SCENE --shard "$SLURM_ARRAY_TASK_ID/N" OPTIONS --out
/// OUT/shard-<task>` as an array of `shards` tasks, and `magvine VERB merge OUT/shard-0 ... --out OUT MERGE_OPTIONS`.
struct SlurmBatch {
  std::string verb;           ///< "trials" or "design"
  std::string scene;          ///< as given
  std::string out;            ///< the merged batch's folder (the shards' go in it)
  std::string options;        ///< the shards' other options, shell words
  std::string merge_options;  ///< the merge's other options, shell words
  int cpus = 1;               ///< per task
  SlurmOptions slurm;
};
/// Writes JOB.sh (the Slurm array, one shard per task) and JOB.merge.sh (the merge); with `submit` submits them (the
/// merge after the array, --dependency=afterok). The caller has checked the scene.
int write_slurm_jobs(const SlurmBatch& batch);
/// A word for bash: single-quoted ('\'' for a quote inside).
std::string shell_word(const std::string& text);

/// The one report of a failed run (docs/cli.md: failed runs; its metrics.json is written): the cause on stderr,
/// exit 3.
int failed_run(const std::string& cause, const std::filesystem::path& out);

/// For a scene that asks for video (`wanted`, the key `what` of `scene`): loads the video plugin before the run (a
/// plugin that cannot be loaded is an input error, nothing written), or warns that this build skips the videos.
void preload_videos(bool wanted, const std::string& scene, const std::string& what);

/// A progress callback for a run: a ten-step bar with the percentage on stderr, redrawn only when a tenth passes.
std::function<void(double)> progress_bar();

/// `magvine design DESIGN.yaml [--out DIR] [--mpm-check …]` (issue 29; docs/design.md).
struct DesignArgs {
  std::string scene;
  std::string out;
  bool mpm_check = false;
  double mpm_cell_mm = 0.0;  ///< 0: a quarter of the diameter
  int mpm_particles = 4;     ///< particles per cell per axis
  std::string shard;         ///< "I/N": only those starts (docs/cluster.md); empty: all
  SlurmOptions slurm;
};
/// `magvine design DESIGN.yaml` (docs/design.md); with --shard one share of its starts, with --slurm the starts as
/// Slurm jobs (docs/cluster.md).
int run_design(const DesignArgs& args);

struct DesignMergeArgs {
  std::vector<std::string> dirs;
  std::string out;
  std::string scene;  ///< the design file, when not at the path the shards recorded
  bool mpm_check = false;
  double mpm_cell_mm = 0.0;
  int mpm_particles = 4;
};
/// `magvine design merge DIR... --out DIR`: the shards' starts as one machine's design (docs/cluster.md).
int run_design_merge(const DesignMergeArgs& args);

/// `magvine calibrate CALIBRATE.yaml [--out DIR]` (issue 29; docs/design.md#calibration).
struct CalibrateArgs {
  std::string scene;
  std::string out;
};
int run_calibrate(const CalibrateArgs& args);

/// `magvine validate --out DIR`: the robot-mechanics studies (scene/mechanics_study.hpp).
int run_validate(const std::string& out_dir);

}  // namespace magvine::cli
