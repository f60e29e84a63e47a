#pragma once
// The one rule for what a failed run leaves behind (docs/cli.md: failed runs), shared by every scene that writes a
// metrics.json (free space, experiments, MPM). Private to the scene module.

#include <filesystem>

#include <nlohmann/json.hpp>

#include "magvine/core/atomic_file.hpp"

namespace magvine::scene::detail {

/// A failed run's outputs: `metrics` alone, as dir/metrics.json. It must be complete (every key a successful run
/// writes, those of files not written as empty lists or null) and say "failed": true and the failure.
inline void write_failed_run(const std::filesystem::path& dir, const nlohmann::json& metrics) {
  create_output_directory(dir);
  write_file_atomically(dir / "metrics.json", metrics.dump(2) + "\n");
}

}  // namespace magvine::scene::detail
