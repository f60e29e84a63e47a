#pragma once
/// Trial batches (`magvine trials`): seeded perturbed repeats of an experiment towards each target, in parallel, with
/// a summary in the form of thesis table 5.2 (docs/experiments.md: trials).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "magvine/scene/experiment.hpp"
#include "magvine/scene/shards.hpp"

namespace magvine::scene {

/// The scene with its navigator aimed at branch `target` (its end the target point). InputError when the scene has no
/// navigator or no such branch.
ExperimentScene with_target(const ExperimentScene& scene, const std::string& target);

/// The scene perturbed for one trial (TrialPerturbation), deterministic in `seed`.
ExperimentScene perturbed(const ExperimentScene& scene, std::uint64_t seed);

struct TrialOutcome {
  int index = 0;  ///< the trial's place in the whole batch: target-major, repeat-minor (target × repeats + repeat)
  std::string target;
  int repeat = 0;
  std::uint64_t seed = 0;
  bool success = false;
  bool burst = false;            ///< the perturbed pressure burst the vine
  double time_to_target = -1.0;  ///< [s]
  double everted_length = 0.0;   ///< [m]
  double final_error = 0.0;      ///< tip to target [m]
  double max_normal = 0.0;       ///< largest wall normal force on a node [N]
  int retractions = 0;           ///< the navigator's (ExperimentResult::recoveries)
  /// A biopsy scene's puncture (ExperimentResult::puncture): whether it succeeded (−1: not a biopsy scene or the
  /// stop not reached; 0 also when the run reached the stop and failed while aiming), the needle tip's distance from
  /// the nodule's centre and the tip's slide back [m] (NaN: none).
  int biopsy = -1;
  double needle_to_nodule = std::numeric_limits<double>::quiet_NaN();
  double slide_back = std::numeric_limits<double>::quiet_NaN();
  double runtime_s = 0.0;
  /// Why a failed trial failed, one line: the last event that stopped the tip (with its numbers), the branch it was
  /// in, how far from the target it ended and after how many retractions; empty on success.
  std::string reason;
};

/// Runs `repeats` perturbed trials towards each target (branch names; empty: the scene's own target) on `jobs`
/// threads, only `shard`'s share of them; outcomes in index order whatever the threads. `progress` gets (done, total)
/// of the shard's trials. With `runs_dir`, each trial's own outputs (write_experiment_outputs, without videos) go to
/// runs_dir/<target>_r<repeat>: its events, trajectories and metrics, to see why a trial failed.
std::vector<TrialOutcome> run_trials(const ExperimentScene& scene, const std::vector<std::string>& targets, int repeats,
                                     int jobs, const std::function<void(int, int)>& progress = nullptr,
                                     const std::filesystem::path& runs_dir = {}, const Shard& shard = {});

/// What makes shards one batch (magvine/scene/shards.hpp): the scene's fingerprint (its bytes and magvine's version),
/// the targets, the repeats and the shard count.
struct BatchIdentity {
  std::string scene;             ///< the scene file, as given
  std::uint64_t scene_hash = 0;  ///< FNV-1a of its bytes
  std::vector<std::string> targets;
  int repeats = 0;
  Shard shard;
};
/// The identity of a batch of `scene_file` (its bytes read now). InputError when it cannot be read.
BatchIdentity batch_identity(const std::filesystem::path& scene_file, const std::vector<std::string>& targets,
                             int repeats, const Shard& shard);

/// A shard's outputs, atomically into `dir`: shard.json (the identity and every outcome at full precision, for
/// merge_shards) and trials.csv of its own trials.
void write_shard(const BatchIdentity& identity, const std::vector<TrialOutcome>& outcomes,
                 const std::filesystem::path& dir);

/// The whole batch from its shards' folders (`magvine trials merge`): the outcomes in index order, exactly as one
/// machine's run_trials gives them. InputError (one line) when a folder has no shard.json or a malformed one, the
/// shards belong to different batches (scene bytes, version, targets, repeats or count), a shard is missing or given
/// twice, or a trial is not in its shard or not of the batch.
std::vector<TrialOutcome> merge_shards(const std::vector<std::filesystem::path>& dirs);

/// trials.csv (every trial, with the reason of each failure) and summary.csv + summary.md in the form of thesis
/// table 5.2 (target, path length = the everted length at the target [mm], success rate, mean time to target and its
/// SD [s], over the successes; summary.md lists the failures with their reasons below the table), atomically into
/// `dir`.
void write_trial_outputs(const std::vector<TrialOutcome>& outcomes, const std::filesystem::path& dir);

}  // namespace magvine::scene
