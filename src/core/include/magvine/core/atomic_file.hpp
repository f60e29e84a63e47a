#pragma once
/// Atomic output files: write to a temporary file beside the target, then rename over it.
/// A crash or an exception before commit() never leaves a truncated or partial result behind.

#include <filesystem>
#include <fstream>
#include <string>

namespace magvine {

class AtomicFile {
 public:
  /// Opens `<target>.tmp-<pid>-<n>` in the target's folder. Throws InputError if it cannot be created.
  explicit AtomicFile(std::filesystem::path target);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// Removes the temporary file unless commit() succeeded.
  ~AtomicFile();

  /// The stream to write to.
  std::ofstream& stream() { return m_stream; }
  /// Flushes, closes and renames onto the target. Throws InputError on any I/O failure.
  void commit();

 private:
  std::filesystem::path m_target;
  std::filesystem::path m_temp;
  std::ofstream m_stream;
  bool m_committed = false;
};

/// Creates `dir` and its parents if missing; InputError naming the folder if that fails.
void create_output_directory(const std::filesystem::path& dir);

/// Writes `content` to `target` atomically.
void write_file_atomically(const std::filesystem::path& target, const std::string& content);

}  // namespace magvine
