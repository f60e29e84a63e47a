#include "magvine/scene/trials.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <thread>

#include "experiment_internal.hpp"
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/config.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "shard_files.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {

ExperimentScene with_target(const ExperimentScene& scene, const std::string& target) {
  if (!scene.navigator) {
    throw InputError(scene.file, 0, "control.navigator", "trials towards named targets need a navigator");
  }
  const auto branch = anatomy::find_branch(*scene.anatomy->graph, target);
  if (!branch)
    throw InputError("--targets", 0, "", "no branch '" + target + "' in the phantom's graph of " + scene.file);
  ExperimentScene out = scene;
  detail::aim_at(out, *branch);
  return out;
}

ExperimentScene perturbed(const ExperimentScene& scene, std::uint64_t seed) {
  ExperimentScene out = scene;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const TrialPerturbation& p = scene.perturbation;
  const Vec3 offset(p.magnet_position_sd * normal(rng), p.magnet_position_sd * normal(rng),
                    p.magnet_position_sd * normal(rng));
  const double pressure = p.pressure_sd * normal(rng);
  const double modulus = 1.0 + p.material_spread * normal(rng);
  const double yield = 1.0 + p.material_spread * normal(rng);
  if (out.magnets) {
    for (magnetics::Pose& pose : out.magnets->rest_poses) pose.position += offset;
    for (auto& keys : out.magnet_keyframes)
      for (MagnetKeyframe& k : keys) k.position += offset;
  }
  if (out.navigator) out.navigator_offset = offset;
  if (!out.growth.rod) {  // a pushed rod has no pressure
    for (double& v : out.pressure.values) v = std::max(0.0, v + pressure);
  }
  out.vine.wall.modulus *= modulus;
  if (out.growth.rod) {
    robot::RodModel& b = out.growth.rod->body;
    b.bending_stiffness_2 *= modulus;
    b.bending_stiffness_3 *= modulus;
    b.torsional_stiffness *= modulus;
    b.axial_stiffness *= modulus;
    b.shear_stiffness *= modulus;
  }
  out.growth.law.yield_pressure *= yield;
  out.seed = seed;
  return out;
}

std::vector<TrialOutcome> run_trials(const ExperimentScene& scene, const std::vector<std::string>& targets, int repeats,
                                     int jobs, const std::function<void(int, int)>& progress,
                                     const std::filesystem::path& runs_dir, const Shard& shard) {
  if (repeats < 1) throw InputError("--repeats", 0, "", "must be >= 1");
  if (jobs < 1) throw InputError("--jobs", 0, "", "must be >= 1");
  (void)shard_items(0, shard);  // a shard I/N, before any work
  std::vector<ExperimentScene> aimed;
  std::vector<std::string> names;
  if (targets.empty()) {
    aimed.push_back(scene);
    names.push_back(scene.navigator ? scene.navigator->target : std::string("target"));
  } else {
    for (const std::string& t : targets) {
      aimed.push_back(with_target(scene, t));
      names.push_back(t);
    }
  }
  for (ExperimentScene& a : aimed) a.videos.clear();  // trials write no videos (nor record their frames)
  // The shard's trials: every index ≡ shard.index (mod shard.count) of the whole batch.
  const std::vector<int> mine = shard_items(aimed.size() * static_cast<std::size_t>(repeats), shard);
  const int total = static_cast<int>(mine.size());
  if (!runs_dir.empty()) create_output_directory(runs_dir);  // before the threads create their folders in it
  std::vector<TrialOutcome> outcomes(static_cast<std::size_t>(total));
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex report;
  std::exception_ptr failure;
  const auto worker = [&] {
    for (int k = next++; k < total; k = next++) {
      const int i = mine[static_cast<std::size_t>(k)];
      try {
        const std::size_t t = static_cast<std::size_t>(i / repeats);
        const int r = i % repeats;
        // The seed: the scene's, the target's index and the repeat (std::hash of a string is not stable across
        // library versions; the index is).
        const std::uint64_t seed = scene.seed * 1000003ULL + t * 10007ULL + static_cast<std::uint64_t>(r);
        const ExperimentScene trial = perturbed(aimed[t], seed);
        const ExperimentResult res = run_experiment(trial);
        TrialOutcome& o = outcomes[static_cast<std::size_t>(k)];
        o.index = i;
        o.target = names[t];
        o.repeat = r;
        o.seed = seed;
        o.success = res.success;
        o.time_to_target = res.time_to_target;
        const detail::RunFigures f = detail::figures_of(trial, res);
        o.everted_length = f.everted_length;
        o.final_error = f.final_error.value_or(0.0);
        o.max_normal = f.max_normal;
        o.retractions = res.recoveries;
        for (const RunEvent& e : res.events) o.burst = o.burst || e.kind == EventKind::kBurst;
        o.runtime_s = res.runtime_s;
        if (!o.success) o.reason = detail::failure_reason(res, f);
        if (res.puncture) {
          o.biopsy = res.puncture->success ? 1 : 0;
          o.needle_to_nodule = res.puncture->to_nodule;
          o.slide_back = res.puncture->slide;
          if (!res.puncture->success) o.reason = "biopsy: " + res.puncture->why;
        } else if (trial.biopsy && o.success && !res.converged) {
          // Reached the stop, then failed while aiming: no puncture.
          o.biopsy = 0;
          o.reason = "biopsy: the run failed before the puncture: " + res.failure;
        }
        if (!runs_dir.empty()) write_experiment_outputs(trial, res, runs_dir / (names[t] + "_r" + std::to_string(r)));
      } catch (...) {
        const std::lock_guard lock(report);
        if (!failure) failure = std::current_exception();
      }
      const int d = ++done;
      if (progress) {
        const std::lock_guard lock(report);
        progress(d, total);
      }
    }
  };
  std::vector<std::thread> threads;
  for (int j = 1; j < std::min(jobs, total); ++j) threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  return outcomes;
}

namespace {

/// trials.csv: every trial, with the reason of each failure.
void write_trials_csv(std::ostringstream& all, const std::vector<TrialOutcome>& outcomes) {
  all.precision(10);
  all << "target,repeat,seed,success,burst,time_to_target_s,everted_length_m,final_error_m,max_normal_N,"
         "retractions,biopsy,needle_to_nodule_m,slide_back_m,runtime_s,reason\n";
  const auto number = [](double v) { return std::isnan(v) ? std::string() : printf_string("%.10g", v); };
  for (const TrialOutcome& o : outcomes) {
    all << o.target << ',' << o.repeat << ',' << o.seed << ',' << (o.success ? 1 : 0) << ',' << (o.burst ? 1 : 0) << ','
        << (o.success ? std::to_string(o.time_to_target) : std::string()) << ',' << o.everted_length << ','
        << o.final_error << ',' << o.max_normal << ',' << o.retractions << ','
        << (o.biopsy >= 0 ? std::to_string(o.biopsy) : std::string()) << ',' << number(o.needle_to_nodule) << ','
        << number(o.slide_back) << ',' << o.runtime_s << ',' << csv_quoted(o.reason) << '\n';
  }
}

}  // namespace

void write_trial_outputs(const std::vector<TrialOutcome>& outcomes, const std::filesystem::path& dir) {
  std::ostringstream all;
  write_trials_csv(all, outcomes);
  std::ostringstream csv;
  std::ostringstream md;
  // A column for the navigator's retractions (Navigator::Recovery) where any trial had one.
  const bool retracted =
      std::any_of(outcomes.begin(), outcomes.end(), [](const TrialOutcome& o) { return o.retractions > 0; });
  csv << "target,path_length_mm,successes,trials,success_rate,mean_time_s,sd_time_s,retractions\n";
  md << "| target | path length [mm] | success | mean time [s] | SD [s] |" << (retracted ? " retractions |" : "")
     << "\n|---|---|---|---|---|" << (retracted ? "---|" : "") << "\n";
  std::vector<std::string> order;
  for (const TrialOutcome& o : outcomes) {
    if (std::find(order.begin(), order.end(), o.target) == order.end()) order.push_back(o.target);
  }
  char line[256];
  for (const std::string& target : order) {
    int n = 0;
    int ok = 0;
    double sum_t = 0.0;
    double sum_t2 = 0.0;
    double sum_l = 0.0;
    int retractions = 0;
    for (const TrialOutcome& o : outcomes) {
      if (o.target != target) continue;
      ++n;
      retractions += o.retractions;
      if (!o.success) continue;
      ++ok;
      sum_t += o.time_to_target;
      sum_t2 += o.time_to_target * o.time_to_target;
      sum_l += o.everted_length;
    }
    const double mean = ok > 0 ? sum_t / ok : std::nan("");
    const double sd = ok > 1 ? std::sqrt(std::max(0.0, (sum_t2 - ok * mean * mean) / (ok - 1))) : std::nan("");
    const double length = ok > 0 ? 1e3 * sum_l / ok : std::nan("");
    std::snprintf(line, sizeof line, "%s,%.1f,%d,%d,%.3f,%.2f,%.2f,%d\n", target.c_str(), length, ok, n,
                  static_cast<double>(ok) / n, mean, sd, retractions);
    csv << line;
    // A table cell with no value (no success, or one: no SD) reads as a dash, not "nan".
    const auto cell = [](double value, const char* format) {
      if (!std::isfinite(value)) return std::string("—");
      char text[32];
      std::snprintf(text, sizeof text, format, value);
      return std::string(text);
    };
    md << "| " << target << " | " << cell(length, "%.0f") << " | " << ok << '/' << n << " | " << cell(mean, "%.1f")
       << " | " << cell(sd, "%.1f") << " |";
    if (retracted) md << ' ' << retractions << " |";
    md << '\n';
  }
  bool failures = false;
  for (const TrialOutcome& o : outcomes) {
    if (o.success) continue;
    if (!failures) md << "\nFailures:\n\n";
    failures = true;
    md << "- " << o.target << ", repeat " << o.repeat << " (seed " << o.seed << "): " << o.reason << "\n";
  }
  create_output_directory(dir);
  write_file_atomically(dir / "trials.csv", all.str());
  write_file_atomically(dir / "summary.csv", csv.str());
  write_file_atomically(dir / "summary.md", md.str());
}

namespace {

/// A trial as JSON (nlohmann writes NaN as null; outcome_of reads null back as NaN).
nlohmann::json outcome_json(const TrialOutcome& o) {
  return {{"index", o.index},
          {"target", o.target},
          {"repeat", o.repeat},
          {"seed", o.seed},
          {"success", o.success},
          {"burst", o.burst},
          {"time_to_target_s", o.time_to_target},
          {"everted_length_m", o.everted_length},
          {"final_error_m", o.final_error},
          {"max_normal_N", o.max_normal},
          {"retractions", o.retractions},
          {"biopsy", o.biopsy},
          {"needle_to_nodule_m", o.needle_to_nodule},
          {"slide_back_m", o.slide_back},
          {"runtime_s", o.runtime_s},
          {"reason", o.reason}};
}

TrialOutcome outcome_of(const nlohmann::json& j) {
  // JSON has no NaN: nlohmann writes NaN and ±inf as null, read back as NaN.
  const auto number = [](const nlohmann::json& v) {
    return v.is_null() ? std::numeric_limits<double>::quiet_NaN() : v.get<double>();
  };
  TrialOutcome o;
  o.index = j.at("index").get<int>();
  o.target = j.at("target").get<std::string>();
  o.repeat = j.at("repeat").get<int>();
  o.seed = j.at("seed").get<std::uint64_t>();
  o.success = j.at("success").get<bool>();
  o.burst = j.at("burst").get<bool>();
  o.time_to_target = number(j.at("time_to_target_s"));
  o.everted_length = number(j.at("everted_length_m"));
  o.final_error = number(j.at("final_error_m"));
  o.max_normal = number(j.at("max_normal_N"));
  o.retractions = j.at("retractions").get<int>();
  o.biopsy = j.at("biopsy").get<int>();
  o.needle_to_nodule = number(j.at("needle_to_nodule_m"));
  o.slide_back = number(j.at("slide_back_m"));
  o.runtime_s = number(j.at("runtime_s"));
  o.reason = j.at("reason").get<std::string>();
  return o;
}

}  // namespace

BatchIdentity batch_identity(const std::filesystem::path& scene_file, const std::vector<std::string>& targets,
                             int repeats, const Shard& shard) {
  return {scene_file.string(), scene_fingerprint(scene_file), targets, repeats, shard};
}

namespace {

const detail::ShardKind& trials_shards() {
  static const detail::ShardKind kind{"magvine_trials_shard",
                                      "trials merge",
                                      "magvine trials --shard I/N",
                                      "trials",
                                      "trial",
                                      {{"targets", "--targets"}, {"repeats", "--repeats"}}};
  return kind;
}

}  // namespace

void write_shard(const BatchIdentity& identity, const std::vector<TrialOutcome>& outcomes,
                 const std::filesystem::path& dir) {
  nlohmann::json j = detail::shard_header(trials_shards(), identity.scene, identity.scene_hash, identity.shard);
  j["targets"] = identity.targets;
  j["repeats"] = identity.repeats;
  nlohmann::json rows = nlohmann::json::array();
  for (const TrialOutcome& o : outcomes) rows.push_back(outcome_json(o));
  j["trials"] = rows;
  create_output_directory(dir);
  write_file_atomically(dir / "shard.json", j.dump(1) + "\n");
  std::ostringstream table;
  write_trials_csv(table, outcomes);
  write_file_atomically(dir / "trials.csv", table.str());
}

std::vector<TrialOutcome> merge_shards(const std::vector<std::filesystem::path>& dirs) {
  nlohmann::json first;
  const std::vector<detail::ShardItem> items = detail::read_shards(
      dirs, trials_shards(),
      [](const nlohmann::json& head) {
        // targets × repeats (no targets: the scene's own one)
        return std::max<std::size_t>(1, head.at("targets").size()) * head.at("repeats").get<std::size_t>();
      },
      first);
  std::vector<TrialOutcome> all;
  for (const detail::ShardItem& item : items) {
    try {
      all.push_back(outcome_of(item.json));
    } catch (const nlohmann::json::exception& e) {
      throw InputError(item.file, 0, "trials", std::string("not a shard file: ") + e.what());
    }
  }
  return all;
}

}  // namespace magvine::scene
