#pragma once
// The `magvine mpm SCENE.yaml` verb and `magvine study mpm-beam` (MPM module; without it both say so and exit 2).

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace magvine::cli {

class MpmCommand {
 public:
  /// Adds `mpm` to `app` and `mpm-beam` to the `study` subcommand.
  void attach(CLI::App& app, CLI::App& study);
  bool parsed() const;
  int run();

 private:
  int run_scene();
  int run_study();

  CLI::App* m_cmd = nullptr;
  CLI::App* m_study = nullptr;
  std::string m_scene;
  std::string m_out;
  std::string m_study_out;
  int m_jobs = 0;
  std::string m_study_model = "plane-strain";
  std::string m_study_frame = "updated";
  std::string m_study_fields = "elastica";
  std::vector<std::string> m_study_resolutions;
  std::vector<double> m_study_field_mt;
  double m_study_implicit = 0.0;
};

}  // namespace magvine::cli
