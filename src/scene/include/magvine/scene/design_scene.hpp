#pragma once
/// Design files (`magvine design DESIGN.yaml`, issue 29; format in docs/design.md): a free-space rod scene as
/// `magvine run` takes it plus a `design:` section, and the outputs of a design: design.json, the designed rod as a
/// scene (scene.yaml) that `magvine run` reproduces, its shape and the target.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "magvine/design/design.hpp"
#include "magvine/scene/experiment_scene.hpp"
#include "magvine/scene/free_space.hpp"
#include "magvine/scene/shards.hpp"

namespace magvine::scene {

/// design.method: `least-squares` (default: Levenberg–Marquardt with the exact Jacobian), `lbfgsb` (L-BFGS-B with the
/// exact adjoint gradient) or `bayesian` (the derivative-free baseline).
using DesignMethod = design::DesignMethod;

/// The method's name in files.
const char* method_name(DesignMethod m);

struct DesignScene {
  FreeSpaceScene scene;
  design::DesignProblem problem;
  DesignMethod method = DesignMethod::least_squares;
  int max_iterations = 100;       ///< design.iterations (the Bayesian baseline: evaluations after its initial ones)
  int starts = 1;                 ///< design.starts: random starts (seeds seed, seed + 1, …), the best kept
  int field_stages = 1;           ///< design.continuation: stages of the field continuation (1: none)
  std::uint64_t seed = 1;         ///< the scene's seed: the random first design
  std::string file;               ///< as given (messages)
  std::string text;               ///< the file's text: scene.yaml is written from it
  double length_unit = 1e-3;      ///< one file length unit [m]
  bool circular_section = false;  ///< robot.section.shape is circle (the MPM check needs it)
  /// A follow-the-leader insertion along an airway graph (design.insertion.path: {anatomy, branch}): the anatomy
  /// entry as written (for experiment.yaml), the branch, the lumen radius at the path's end, and the insertion speed
  /// of the experiment [m/s].
  struct AirwayPath {
    std::string anatomy_yaml;
    std::string branch;
    double end_radius = 0.0;
    double insertion_speed = 0.01;
  };
  std::optional<AirwayPath> airway;
};

/// Whether `file` is a design file (YAML with a top-level `design:`); false for anything unreadable.
bool is_design_scene(const std::filesystem::path& file);

/// Reads and checks a design file; InputError (exit 2) naming the file, line and key otherwise.
DesignScene load_design_scene(const std::filesystem::path& file);
/// `cache` (optional) shares the anatomies of insertion paths along airway graphs between loads.
DesignScene parse_design_scene(const std::string& text, const std::string& file_label, AnatomyCache* cache = nullptr);

/// Runs the scene's method from its seeded random starts (design::multi_start_design).
design::DesignResult run_design(const DesignScene& scene, const std::function<void(int, double)>& progress = {});

/// One shard of the scene's starts (`magvine design --shard I/N`, docs/cluster.md): design::design_start for each
/// start ≡ I (mod N) of design.starts, in order, with its index. `progress` gets (done, total) of the shard's starts.
/// InputError for the Bayesian baseline (one run: no starts to share).
std::vector<std::pair<int, design::DesignResult>> run_design_shard(const DesignScene& scene, const Shard& shard,
                                                                   const std::function<void(int, int)>& progress = {});

/// A design shard's outputs, atomically into `dir`: shard.json (magvine/scene/shards.hpp) with the scene file (as given
/// and as an absolute path, for the merge), its fingerprint (scene_fingerprint, taken before the run: an edit during
/// it is another sweep), design.starts and every start's result at full precision (design, equilibria, counts,
/// history).
void write_design_shard(const std::filesystem::path& scene_file, std::uint64_t fingerprint, const DesignScene& scene,
                        const Shard& shard, const std::vector<std::pair<int, design::DesignResult>>& starts,
                        const std::filesystem::path& dir);

/// A design sweep joined from its shards (`magvine design merge`): the scene, read again from the file the shards
/// name, and the result one machine's run_design gives (design::join_starts of the starts in order; its time the sum
/// of the starts' times).
struct MergedDesign {
  DesignScene scene;
  design::DesignResult result;
};
/// The scene is read from `scene_file` when given (shards copied off the cluster), else from the absolute path the
/// shards recorded; it keeps the name the shards were given (the outputs' headers quote it, as one machine's do).
/// InputError (one line) when a folder has no design shard.json or a malformed one, the shards are of different
/// sweeps (scene bytes, magvine version, count), a shard is missing or given twice, a start is not in its shard or
/// missing, or the scene file does not have the bytes the shards ran.
MergedDesign merge_design_shards(const std::vector<std::filesystem::path>& dirs,
                                 const std::filesystem::path& scene_file = {});

/// The designed rod as a scene file: the design file without `design:`, its `robot.magnetisation` replaced by the
/// design's sections (file units, 17 significant digits) and, with a free field, `magnets` by the designed uniform
/// field.
std::string designed_scene_yaml(const DesignScene& scene, const design::Design& design);

/// The designed catheter pushed through the anatomy of an insertion along an airway graph (issue 29, patient-specific
/// designs): a `robot.kind: rod` experiment with the design's sections, inserted from the base at the path's speed
/// from its first step's length, the design's field of step c as control.field from the time step c's length is
/// inserted (linear between), and the path's end as the target (within its lumen radius).
std::string designed_experiment_yaml(const DesignScene& scene, const design::Design& design);

/// Writes DIR/design.json, DIR/scene.yaml, DIR/shape.csv (the design's equilibrium) and DIR/target.csv (each target
/// point, the body's point at its arc length and their distance), each atomically (the folder is created); with an
/// insertion along an airway graph also DIR/experiment.yaml (designed_experiment_yaml).
void write_design_outputs(const DesignScene& scene, const design::DesignResult& result,
                          const std::filesystem::path& dir);

/// The MPM check of a design (issue 29): the designed rod (the fully inserted one with insertion) as a 3D MPM scene
/// in the thesis's own method. A cylinder of the rod's diameter from a clamp behind the base to the tip, its sections
/// as slabs of the design's remanence along the base axis (which must be a coordinate axis), the design's uniform
/// field, gravity as the scene's, the material of the file's robot (circular sections only), and a probe at each target
/// point's arc length on the straight rod (but the first, the clamped base). `cell`: the grid spacing [m] (0: a quarter
/// of the diameter); `particles_per_cell` per axis (4: the Zhao beam study's choice, docs/validation.md). The damping
/// is about twice the rod's first bending frequency (near critical for that mode); the run stops when the probes settle
/// (every probe moved less than 1e-4 L over 0.05 s) or after `duration`. InputError when the design cannot be
/// written as one (an oblique base, a rectangular section, a field that is not uniform).
std::string design_mpm_scene_yaml(const DesignScene& scene, const design::Design& design, double cell = 0.0,
                                  int particles_per_cell = 4, double duration = 2.0);

/// Writes the design's MPM scene and parses it as magvine mpm would (particles sampled), writing nothing: an
/// InputError before a design's outputs are written (MPM builds only).
void check_design_mpm_scene(const DesignScene& scene, const design::Design& design, double cell = 0.0,
                            int particles_per_cell = 4);

/// The rod against MPM: each probe's final position against the rod equilibrium's point at its arc length (the target
/// points but the clamped first).
struct DesignMpmCheck {
  double rms = 0.0;         ///< rod–MPM [m]
  double max = 0.0;         ///< [m]
  double target_rms = 0.0;  ///< MPM against the target [m]
  bool settled = false;
  double simulated_s = 0.0;
  double runtime_s = 0.0;
  long steps = 0;
  long particles = 0;
  std::string failure;  ///< the MPM run's, when it failed
};

/// Writes DIR/mpm_check.yaml (design_mpm_scene_yaml), runs it (MPM builds only: InputError otherwise) into
/// DIR/mpm_check/ (magvine mpm's outputs), and returns the comparison.
DesignMpmCheck run_design_mpm_check(const DesignScene& scene, const design::DesignResult& result,
                                    const std::filesystem::path& dir, double cell = 0.0, int particles_per_cell = 4,
                                    const std::function<void(double)>& progress = {});

/// Adds the check to DIR/design.json as `mpm_check`: rms_m, max_m, target_rms_m, settled, simulated_s, runtime_s,
/// steps, particles, failure.
void add_mpm_check_to_design_json(const DesignMpmCheck& check, const std::filesystem::path& dir);

}  // namespace magvine::scene
