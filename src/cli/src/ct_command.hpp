#pragma once
// The `magvine ct import SEG.nii.gz --out DIR` verb and `magvine study ct-import` (CT module; without it both say so
// and exit 2).

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace magvine::cli {

class CtCommand {
 public:
  /// Adds `ct import` to `app` and `ct-import` to the `study` subcommand.
  void attach(CLI::App& app, CLI::App& study);
  bool parsed() const;
  int run();

 private:
  int run_import();
  int run_study();

  CLI::App* m_import = nullptr;
  CLI::App* m_study = nullptr;
  std::vector<std::string> m_study_segmentations, m_study_references;
  std::string m_study_out;
  std::string m_file;
  std::string m_out;
  std::string m_frame = "ras";
  int m_label = 1;
  double m_voxel_mm = 0.0;
  int m_smoothing = 2;
  double m_adaptivity = 0.1;
};

}  // namespace magvine::cli
