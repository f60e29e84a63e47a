#include "ct_command.hpp"

#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "magvine/config.hpp"
#include "magvine/core/error.hpp"
#if MAGVINE_WITH_CT
#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/anatomy/mesh_report.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/text.hpp"
#include "magvine/ct/import.hpp"
#include "magvine/studies/ct_study.hpp"
#endif

namespace magvine::cli {

void CtCommand::attach(CLI::App& app, CLI::App& study) {
  auto* ct = app.add_subcommand("ct", "CT segmentations (NIfTI label maps) to airway anatomy");
  ct->require_subcommand(1);
  m_import = ct->add_subcommand(
      "import",
      "label map -> DIR/airway.stl (mm), graph.json (as mesh graph), report.json (as mesh check --json), "
      "import.json (what the import did)");
  m_import->add_option("file", m_file, "NIfTI label map (.nii or .nii.gz)")->required();
  m_import->add_option("--out", m_out, "output folder")->required();
  m_import->add_option("--label", m_label, "the airway lumen's label (default 1)");
  m_import->add_option("--frame", m_frame, "world frame of the outputs: ras (NIfTI's, default) | lps (DICOM/Slicer)");
  m_import->add_option("--voxel", m_voxel_mm, "level-set voxel [mm] (default: the map's finest voxel edge)");
  m_import->add_option("--smoothing", m_smoothing, "Gaussian passes over the signed distance, 0-20 (default 2)");
  m_import->add_option("--adaptivity", m_adaptivity, "meshing adaptivity 0-1: 0 uniform, 1 fewest (default 0.1)");
  m_study = study.add_subcommand("ct-import",
                                 "CT import's voxel, smoothing and adaptivity against reference surfaces "
                                 "of the same label maps: error against runtime (CSV)");
  m_study->add_option("--segmentation", m_study_segmentations, "label maps (.nii.gz), one per reference")->required();
  m_study->add_option("--reference", m_study_references, "reference surfaces (STL, mm), one per label map")->required();
  m_study->add_option("--out", m_study_out, "output folder")->required();
}

bool CtCommand::parsed() const {
  return m_import->parsed() || m_study->parsed();
}

int CtCommand::run() {
  if (!config::kWithCt) {
    throw InputError(std::string(m_import->parsed() ? "ct import" : "study ct-import") +
                     ": this magvine was built without the CT module (configure with -DMAGVINE_WITH_CT=ON)");
  }
  return m_import->parsed() ? run_import() : run_study();
}

#if MAGVINE_WITH_CT
int CtCommand::run_import() {
  ct::ImportOptions options;
  if (m_frame != "ras" && m_frame != "lps")
    throw InputError("--frame", 0, "", "must be ras or lps (got '" + m_frame + "')");
  options.surface.label = m_label;
  options.surface.frame = m_frame == "lps" ? ct::Frame::kLps : ct::Frame::kRas;
  if (!(m_voxel_mm >= 0.0)) throw InputError("--voxel", 0, "", "must be a length >= 0 (0 = automatic)");
  options.surface.voxel = 1e-3 * m_voxel_mm;
  options.surface.smoothing = m_smoothing;
  options.surface.adaptivity = m_adaptivity;
  const ct::ImportResult result = ct::import_to_folder(m_file, m_out, options);
  for (const std::string& note : result.surface.notes) std::cerr << "magvine ct import: note: " << note << '\n';
  for (const std::string& w : result.surface.warnings) std::cerr << "magvine ct import: warning: " << w << '\n';
  std::cout << ct::import_summary(m_file, result);
  return 0;
}

int CtCommand::run_study() {
  if (m_study_segmentations.size() != m_study_references.size()) {
    throw InputError("--reference", 0, "", "give one reference surface per --segmentation");
  }
  std::vector<studies::CtStudyCase> cases;
  for (std::size_t n = 0; n < m_study_segmentations.size(); ++n) {
    const std::filesystem::path seg = m_study_segmentations[n];
    // Patient folders (…/Patient1/bronchialTree.nii.gz) name the case by the folder.
    std::string name = seg.parent_path().filename().string();
    if (name.empty()) name = seg.stem().string();
    cases.push_back({name, seg, m_study_references[n]});
  }
  studies::run_ct_study(cases, m_study_out, [](const studies::CtStudyRun& r) {
    std::cerr << printf_string(
        "  %-10s voxel x%.1f smoothing %d adaptivity %.1f: %7zu triangles, %s genus %3ld, "
        "volume %+6.2f %%, mean distance %.3f mm (%.2f voxel), max %.2f mm, %.2f s, "
        "trachea %.1f mm, generations 0-%d\n",
        r.name.c_str(), r.voxel_factor, r.smoothing, r.adaptivity, r.triangles,
        r.watertight ? "watertight" : "OPEN      ", r.genus, 100.0 * r.volume_rel_err, 1e3 * r.mean_distance,
        r.mean_distance / r.finest_voxel, 1e3 * r.max_distance, r.seconds, 1e3 * r.trachea_diameter,
        r.deepest_generation);
  });
  std::cerr << "magvine study ct-import: " << m_study_out << "/ct_study.csv (tools/plot_ct_study.py " << m_study_out
            << ")\n";
  return 0;
}
#else
int CtCommand::run_import() {
  return 2;
}
int CtCommand::run_study() {
  return 2;
}
#endif

}  // namespace magvine::cli
