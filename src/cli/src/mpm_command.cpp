#include "mpm_command.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <thread>

#include "commands.hpp"
#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#if MAGVINE_WITH_MPM
#include "magvine/core/units.hpp"
#include "magvine/scene/mpm_scene.hpp"
#include "magvine/studies/mpm_study.hpp"
#endif

namespace magvine::cli {

void MpmCommand::attach(CLI::App& app, CLI::App& study) {
  m_cmd = app.add_subcommand("mpm", "magnetic MPM: soft magnetic bodies of any shape in a field (metrics.json, "
                                    "probes.csv, PLY particle snapshots); exit 3 when the solver fails");
  m_cmd->add_option("scene", m_scene, "MPM scene file (YAML with an mpm: section)")->required();
  m_cmd->add_option("--out", m_out, "output folder (default: runs/<scene name>)");
  m_study = study.add_subcommand("mpm-beam", "MPM on the Zhao beam vs the elastica at five particle densities: "
                                             "error against runtime (CSV)");
  m_study->add_option("--out", m_study_out, "output folder")->required();
  m_study->add_option("--jobs", m_jobs, "beams run at once (default: every core)")->check(CLI::Range(1, 1024));
  m_study
      ->add_option("--model", m_study_model,
                   "plane-strain (2D, the reference code's), plane-stress (2D) or 3d (the real 5 mm wide beam)")
      ->capture_default_str()
      ->check(CLI::IsMember({"plane-strain", "plane-stress", "3d"}));
  m_study
      ->add_option("--frame", m_study_frame,
                   "updated (particles carry F; the thesis's) or total (F from the reference grid: "
                   "total-Lagrangian, for bodies that bend but do not flow)")
      ->capture_default_str()
      ->check(CLI::IsMember({"updated", "total"}));
  CLI::Option* fields =
      m_study
          ->add_option("--fields", m_study_fields,
                       "elastica: 7-25 mT, all past buckling; experiment: Zhao et al.'s 5, 7, 10, 15, 25, 40 mT")
          ->capture_default_str()
          ->check(CLI::IsMember({"elastica", "experiment"}));
  m_study->add_option("--field", m_study_field_mt, "a field to run [mT], instead of --fields; repeat for several")
      ->check(CLI::Range(0.1, 1000.0))
      ->excludes(fields);
  m_study
      ->add_option("--implicit", m_study_implicit,
                   "implicit steps of R explicit stable steps (Newton on the incremental potential; at most a quarter "
                   "of the 1 ms kick; default: explicit)")
      ->check(CLI::Range(1.0, 1000.0));
  m_study->add_option("--resolution", m_study_resolutions,
                      "CxP: C cells through the thickness, P particles per cell per axis; repeat for several "
                      "(default: 3x2 3x3 3x4 4x4 5x4)");
}

bool MpmCommand::parsed() const { return m_cmd->parsed() || m_study->parsed(); }

int MpmCommand::run() {
  if (!config::kWithMpm) {
    throw InputError(std::string(m_cmd->parsed() ? "mpm" : "study mpm-beam") +
                     ": this magvine was built without the MPM module (configure with -DMAGVINE_WITH_MPM=ON)");
  }
  return m_cmd->parsed() ? run_scene() : run_study();
}

#if MAGVINE_WITH_MPM
int MpmCommand::run_scene() {
  const std::filesystem::path out =
      m_out.empty() ? std::filesystem::path("runs") / std::filesystem::path(m_scene).stem() : std::filesystem::path(m_out);
  const scene::MpmScene sc = scene::load_mpm_scene(m_scene);
  std::cerr << "magvine mpm: " << sc.positions.size() << " particles in " << sc.body_names.size()
            << (sc.body_names.size() == 1 ? " body" : " bodies") << ", " << sc.dimension << "D, step "
            << sc.time_step * 1e6 << " us (stable bound " << sc.stable_step * 1e6 << " us), " << sc.duration
            << " s simulated\n";
  preload_videos(sc.video.has_value(), m_scene, "mpm.video");
  const scene::MpmResult r = scene::run_mpm_scene(sc, progress_bar());
  std::cerr << '\n';
  scene::write_mpm_outputs(sc, r, out);  // a failed run: metrics.json only, saying so
  if (!r.ok) return failed_run(r.failure, out);
  std::cerr << "magvine mpm: " << r.steps << " steps, " << r.time << " s simulated" << (r.settled ? " (at rest)" : "")
            << " in " << r.runtime_s << " s ("
            << static_cast<double>(sc.positions.size()) * static_cast<double>(r.steps) / r.runtime_s / 1e6
            << " M particle-steps/s)";
  for (std::size_t q = 0; q < sc.probes.size(); ++q) {
    const Vec3 d = (r.samples.back().probes[q] - r.samples.front().probes[q]) / kMmToM;
    std::cerr << "; " << sc.probes[q].name << " moved (" << d.x() << ", " << d.y() << ", " << d.z() << ") mm";
  }
  std::cerr << " -> " << out.string() << "/{metrics.json,probes.csv,snapshots/}\n";
  return 0;
}

int MpmCommand::run_study() {
  const int jobs = m_jobs > 0 ? m_jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::cerr << "magvine study mpm-beam: " << m_study_model << ", " << m_study_frame << " frame, ";
  if (m_study_field_mt.empty()) {
    std::cerr << m_study_fields << " fields, ";
  } else {
    for (double b : m_study_field_mt) std::cerr << b << ' ';
    std::cerr << "mT, ";
  }
  if (m_study_implicit > 0.0) {
    std::cerr << "implicit steps of " << m_study_implicit << " explicit ones";
  } else {
    std::cerr << "explicit steps";
  }
  std::cerr << ", on " << jobs << " threads\n";
  studies::MpmBeamStudyOptions options;
  options.model = m_study_model == "plane-stress" ? studies::ZhaoModel::kPlaneStress
                  : m_study_model == "3d"         ? studies::ZhaoModel::k3D
                                                  : studies::ZhaoModel::kPlaneStrain;
  options.total_lagrangian = m_study_frame == "total";
  if (m_study_fields == "experiment") options.fields = studies::zhao_experiment_fields();
  if (!m_study_field_mt.empty()) {
    options.fields.clear();
    for (double b : m_study_field_mt) options.fields.push_back(b * kMtToT);
  }
  options.step_ratio = m_study_implicit;
  if (!m_study_resolutions.empty()) {
    options.resolutions.clear();
    for (const std::string& r : m_study_resolutions) {
      int cells = 0, ppc = 0;
      char x = 0, extra = 0;
      if (std::sscanf(r.c_str(), "%d%c%d%c", &cells, &x, &ppc, &extra) != 3 || x != 'x' || cells < 1 || cells > 16 ||
          ppc < 1 || ppc > 8) {
        throw InputError("--resolution", 0, "", "must be CxP with 1 <= C <= 16 cells, 1 <= P <= 8 (got '" + r + "')");
      }
      options.resolutions.emplace_back(cells, ppc);
    }
  }
  studies::run_mpm_beam_study(m_study_out, jobs, options, [](const studies::ZhaoPoint& p) {
    std::fprintf(stderr, "  %s, %d cells x %d particles/cell, %4.1f mT: delta/L %.4f (elastica %.4f) in %.1f s%s\n",
                 studies::zhao_model_name(p.model), p.cells, p.particles_per_cell, p.field * 1e3, p.deflection,
                 p.reference, p.seconds,
                 p.ok ? (p.settled ? "" : " NOT at rest") : (" FAILED: " + p.failure).c_str());
  });
  std::cerr << "magvine study mpm-beam: " << m_study_out << "/mpm_beam_study.csv, mpm_beam_summary.csv\n";
  return 0;
}
#else
int MpmCommand::run_scene() { return 0; }
int MpmCommand::run_study() { return 0; }
#endif

}  // namespace magvine::cli
