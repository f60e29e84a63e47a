#pragma once
// The `magvine phantom KIND ...` verb: one CLI11 subcommand per generated phantom kind (anatomy/phantom.hpp).

#include <CLI/CLI.hpp>

#include <string>
#include <utility>
#include <vector>

#include "magvine/anatomy/phantom.hpp"

namespace magvine::cli {

/// Owns the parsed options of every kind; attach() before parsing, run() after, when parsed().
class PhantomCommand {
 public:
  void attach(CLI::App& app);
  bool parsed() const;
  /// Generates the chosen phantom, writes it (STL in mm + graph + metadata) and prints a summary. InputError for
  /// a bad parameter (naming it) or an --out that is not an .stl path.
  int run();

 private:
  CLI::App* m_cmd = nullptr;
  std::vector<CLI::App*> m_kinds;
  std::vector<std::pair<anatomy::PhantomKind, anatomy::PhantomParams>> m_params;  // SI, one per kind
  std::string m_out;
  std::string m_table{anatomy::to_string(anatomy::BronchialTreeParams{}.table)};
  bool m_open = false;
};

}  // namespace magvine::cli
