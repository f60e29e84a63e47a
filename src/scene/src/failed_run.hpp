#pragma once
// The one rule for what a failed run leaves behind (docs/cli.md: failed runs), shared by every scene that writes a
// metrics.json (free space, experiments, MPM). Private to the scene module.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <system_error>

#include "magvine/core/atomic_file.hpp"

namespace magvine::scene::detail {

/// A failed run's outputs: `metrics` alone, as dir/metrics.json. It must be complete (every key a successful run
/// writes, those of files not written as empty lists or null) and say "failed": true and the failure. `stale`: the
/// other files and folders a successful run of this kind writes, removed where an earlier run into `dir` left them
/// (so that nothing in dir looks like this run's but its metrics).
inline void write_failed_run(const std::filesystem::path& dir, const nlohmann::json& metrics,
                             std::span<const char* const> stale = {}) {
  create_output_directory(dir);
  for (const char* name : stale) {
    std::error_code ec;
    std::filesystem::remove_all(dir / name, ec);
  }
  write_file_atomically(dir / "metrics.json", metrics.dump(2) + "\n");
}

}  // namespace magvine::scene::detail
