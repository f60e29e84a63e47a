#pragma once
/// Error types and the process exit-code convention of DESIGN.md.

#include <stdexcept>
#include <string>

namespace magvine {

/// Exit codes of the `magvine` executable.
enum class ExitCode : int {
  kOk = 0,              ///< success
  kGoalFailed = 1,      ///< the simulation ran but missed its goal (only where a verb documents it)
  kBadInput = 2,        ///< bad input: one line on stderr naming file, line/key and the problem
  kNumericalFailure = 3 ///< NaN, divergence, no convergence: names the step and cause
};

/// Bad input detected at a boundary (file, mesh, command line). The message is one line that names the
/// file, the line or key, and what is wrong, e.g. `magnets.yaml:7: magnets[0].diameter: must be > 0 (got -3)`.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
  /// Formats `<file>:<line>: <where>: <what>`; `line` <= 0 omits the line.
  InputError(const std::string& file, int line, const std::string& where, const std::string& what)
      : std::runtime_error(format(file, line, where, what)) {}

 private:
  static std::string format(const std::string& file, int line, const std::string& where, const std::string& what);
};

/// Numerical failure (NaN, divergence, no convergence) that stops a run; exit code 3.
class NumericalError : public std::runtime_error {
 public:
  explicit NumericalError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace magvine
