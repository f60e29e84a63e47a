// Trial batches on a cluster (docs/cluster.md): `magvine trials merge` joins shards into the batch one machine
// writes, and `magvine trials SCENE --slurm JOB.sh` writes the batch as a Slurm array of shards and a merge job that
// waits for it (and with --submit submits both).

#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/scene/experiment_scene.hpp"
#include "magvine/scene/trials.hpp"

namespace magvine::cli {
namespace fs = std::filesystem;

int run_trials_merge(const TrialsMergeArgs& args) {
  if (args.out.empty()) throw InputError("--out", 0, "", "name the folder for the merged batch");
  std::vector<fs::path> dirs(args.dirs.begin(), args.dirs.end());
  const std::vector<scene::TrialOutcome> outcomes = scene::merge_shards(dirs);
  scene::write_trial_outputs(outcomes, args.out);
  std::ifstream md(fs::path(args.out) / "summary.md");
  std::cout << md.rdbuf();
  std::cerr << "magvine trials merge: " << dirs.size() << " shards, " << outcomes.size() << " trials -> "
            << (fs::path(args.out) / "trials.csv").string() << ", summary.csv, summary.md\n";
  return 0;
}

std::string shell_word(const std::string& text) {
  std::string q = "'";
  for (const char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

namespace {

/// Submits `script` with sbatch (`options` before it) and returns the job id it printed (--parsable: "id" or
/// "id;cluster", on the last line of its output). InputError, one line, when it cannot run, fails or prints no id.
std::string submit(const std::string& options, const fs::path& script) {
  const std::string command = "sbatch --parsable " + options + shell_word(script.string());
  FILE* pipe = popen((command + " 2>/dev/null").c_str(), "r");
  if (pipe == nullptr) throw InputError("--submit", 0, "", "cannot run sbatch");
  std::string text;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) text += buffer;
  const int status = pclose(pipe);
  std::string last;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty()) last = line;
  }
  const std::string id = last.substr(0, last.find(';'));
  const bool digits = !id.empty() && std::all_of(id.begin(), id.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (status != 0 || !digits) {
    throw InputError("--submit", 0, "",
                     "sbatch " + script.filename().string() + " failed (exit " + std::to_string(WEXITSTATUS(status)) +
                         "); run it by hand to see why: " + command);
  }
  return id;
}

/// A value for an #SBATCH line: letters, digits and _.,:- only (no space, quote or newline to break the script).
void check_resource(const char* option, const std::string& value) {
  const bool plain = std::all_of(value.begin(), value.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == ',' || c == ':' || c == '-';
  });
  if (!plain) throw InputError(option, 0, "", "must be letters, digits and _.,:- only (got '" + value + "')");
}

}  // namespace

int write_slurm_jobs(const SlurmBatch& batch) {
  if (batch.slurm.shards < 1)
    throw InputError("--shards", 0, "", "--slurm needs --shards N (the array's tasks), N >= 1");
  const fs::path job = fs::absolute(batch.slurm.job);
  if (job.extension() != ".sh")
    throw InputError("--slurm", 0, "", "must name a .sh file (got '" + batch.slurm.job + "')");
  const fs::path exe = fs::read_symlink("/proc/self/exe");
  const fs::path scene = fs::absolute(batch.scene);
  const fs::path out = fs::absolute(batch.out);
  check_resource("--partition", batch.slurm.partition);
  check_resource("--time", batch.slurm.time);
  check_resource("--mem", batch.slurm.mem);
  // #SBATCH --output takes a bare path, with % as its pattern sign.
  const std::string logs = out.string();
  if (std::any_of(logs.begin(), logs.end(), [](char c) {
        return std::isspace(static_cast<unsigned char>(c)) || c == '%' || c == '"' || c == '\'';
      })) {
    throw InputError("--out", 0, "",
                     "a Slurm batch needs an output folder without spaces, quotes or % (got '" + logs + "')");
  }
  const fs::path merge = fs::path(job).replace_extension(".merge.sh");
  const std::string name = "magvine-" + batch.verb;

  std::ostringstream array;
  array << "#!/bin/bash\n"
        << "# magvine " << batch.verb << ' ' << batch.scene << " as a Slurm array of " << batch.slurm.shards
        << " shards (docs/cluster.md), written by magvine.\n"
        << "# Submit with the merge job that waits for it:\n"
        << "#   jid=$(sbatch --parsable " << shell_word(job.string()) << ") && sbatch --dependency=afterok:$jid "
        << shell_word(merge.string()) << "\n"
        << "#SBATCH --job-name=" << name << '\n'
        << "#SBATCH --array=0-" << batch.slurm.shards - 1 << '\n'
        << "#SBATCH --ntasks=1\n"
        << "#SBATCH --cpus-per-task=" << batch.cpus << '\n'
        << "#SBATCH --output=" << (out / "slurm" / "shard-%a.log").string() << '\n';
  if (!batch.slurm.partition.empty()) array << "#SBATCH --partition=" << batch.slurm.partition << '\n';
  if (!batch.slurm.time.empty()) array << "#SBATCH --time=" << batch.slurm.time << '\n';
  if (!batch.slurm.mem.empty()) array << "#SBATCH --mem=" << batch.slurm.mem << '\n';
  array << "set -euo pipefail\n"
        << "exec " << shell_word(exe.string()) << ' ' << batch.verb << ' ' << shell_word(scene.string())
        << " --shard \"$SLURM_ARRAY_TASK_ID/" << batch.slurm.shards << '"' << batch.options << " --out "
        << shell_word((out / "shard-").string()) << "\"$SLURM_ARRAY_TASK_ID\"\n";
  std::ostringstream joiner;
  joiner << "#!/bin/bash\n"
         << "# The merge of " << job.filename().string()
         << "'s shards into what one machine writes (docs/cluster.md), written by magvine.\n"
         << "#SBATCH --job-name=" << name << "-merge\n"
         << "#SBATCH --ntasks=1\n"
         << "#SBATCH --cpus-per-task=1\n"
         << "#SBATCH --output=" << (out / "slurm" / "merge.log").string() << '\n';
  // The merge gets the shards' resources (a design's merge may run its MPM check).
  if (!batch.slurm.partition.empty()) joiner << "#SBATCH --partition=" << batch.slurm.partition << '\n';
  if (!batch.slurm.time.empty()) joiner << "#SBATCH --time=" << batch.slurm.time << '\n';
  if (!batch.slurm.mem.empty()) joiner << "#SBATCH --mem=" << batch.slurm.mem << '\n';
  joiner << "set -euo pipefail\n"
         << "exec " << shell_word(exe.string()) << ' ' << batch.verb << " merge";
  for (int i = 0; i < batch.slurm.shards; ++i)
    joiner << ' ' << shell_word((out / ("shard-" + std::to_string(i))).string());
  joiner << " --out " << shell_word(out.string()) << batch.merge_options << '\n';

  create_output_directory(out / "slurm");  // Slurm does not create the logs' folder
  if (job.has_parent_path()) create_output_directory(job.parent_path());
  write_file_atomically(job, array.str());
  write_file_atomically(merge, joiner.str());
  fs::permissions(job, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
  fs::permissions(merge, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
  std::cerr << "magvine " << batch.verb << ": " << job.string() << " (" << batch.slurm.shards
            << " shards as a Slurm array), " << merge.string() << " (their merge into " << out.string() << ")\n";
  if (!batch.slurm.submit) {
    std::cout << "jid=$(sbatch --parsable " << shell_word(job.string()) << ") && sbatch --dependency=afterok:$jid "
              << shell_word(merge.string()) << '\n';
    return 0;
  }
  const std::string id = submit("", job);
  std::string merge_id;
  try {
    merge_id = submit("--dependency=afterok:" + id + " ", merge);
  } catch (const InputError&) {
    // The array without its merge would run for nothing: cancel it.
    (void)std::system(("scancel " + id + " > /dev/null 2>&1").c_str());
    throw;
  }
  std::cout << id << ' ' << merge_id << '\n';
  std::cerr << "magvine " << batch.verb << ": submitted the array as job " << id << " and its merge as job " << merge_id
            << '\n';
  return 0;
}

}  // namespace magvine::cli
