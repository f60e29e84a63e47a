#pragma once
// The real CT-derived airway meshes are third-party data kept outside the repository (../shared/airways). Tests
// and benchmarks read them from there, or from $MAGVINE_AIRWAYS_DIR, and skip when they are absent.

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

namespace test {

/// Path of a file in the shared airway folder, or nullopt when the folder or file is missing.
inline std::optional<std::filesystem::path> airway_file(const std::string& name) {
  const char* env = std::getenv("MAGVINE_AIRWAYS_DIR");
  const std::filesystem::path dir = env != nullptr ? std::filesystem::path(env) : std::filesystem::path(MAGVINE_AIRWAYS_DIR);
  std::error_code ec;
  const std::filesystem::path file = dir / name;
  if (!std::filesystem::is_regular_file(file, ec)) return std::nullopt;
  return file;
}

}  // namespace test
