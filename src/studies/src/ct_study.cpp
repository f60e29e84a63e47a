#include "magvine/studies/ct_study.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "magvine/anatomy/mesh_distance.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/ct/import.hpp"

namespace magvine::studies {

namespace {

/// A case read once: its reference surface, its label map and the time the read took.
struct LoadedCase {
  const CtStudyCase& c;
  anatomy::TriangleMesh reference;
  ct::LabelVolume volume;
  double seconds_read = 0.0;
};

CtStudyRun run_once(const LoadedCase& l, double voxel_factor, int smoothing, double adaptivity) {
  CtStudyRun run{.name = l.c.name, .voxel_factor = voxel_factor, .smoothing = smoothing, .adaptivity = adaptivity};
  const std::array<double, 3> h = l.volume.spacing();
  run.finest_voxel = std::min({h[0], h[1], h[2]});
  ct::ImportOptions options;
  options.surface.voxel = voxel_factor * run.finest_voxel;
  options.surface.smoothing = smoothing;
  options.surface.adaptivity = adaptivity;
  const ct::ImportResult r = ct::import_anatomy(l.volume, l.c.segmentation.string(), options);
  run.seconds = l.seconds_read + r.surface.seconds_surface;
  run.triangles = r.report.triangles;
  run.watertight = r.report.watertight;
  run.genus = r.report.genus;
  const double v_ref = std::abs(anatomy::signed_volume(l.reference));
  run.volume_rel_err = (std::abs(anatomy::signed_volume(r.mesh.mesh)) - v_ref) / v_ref;
  const anatomy::SurfaceDistance d = anatomy::symmetric_surface_distance(r.mesh.mesh, l.reference);
  run.mean_distance = d.mean;
  run.rms_distance = d.rms;
  run.max_distance = d.max;
  run.trachea_diameter = r.trachea_diameter;
  run.deepest_generation = r.deepest_generation;
  return run;
}

}  // namespace

void run_ct_study(const std::vector<CtStudyCase>& cases, const std::filesystem::path& dir,
                  const std::function<void(const CtStudyRun&)>& progress) {
  struct Setting {
    double voxel_factor;
    int smoothing;
    double adaptivity;
  };
  const ct::SurfaceOptions defaults;
  std::vector<Setting> settings;
  for (const double f : {1.0, 1.5, 2.0}) settings.push_back({f, defaults.smoothing, defaults.adaptivity});
  for (const int s : {0, 1, 2, 4, 8}) {
    if (s != defaults.smoothing) settings.push_back({1.0, s, defaults.adaptivity});
  }
  for (const double a : {0.0, 0.1, 0.3}) {
    if (a != defaults.adaptivity) settings.push_back({1.0, defaults.smoothing, a});
  }
  std::ostringstream csv;
  csv.precision(9);
  csv << "case,voxel_factor,smoothing,adaptivity,finest_voxel_m,seconds,triangles,watertight,genus,volume_rel_err,"
         "mean_distance_m,rms_distance_m,max_distance_m,trachea_diameter_m,deepest_generation\n";
  for (const CtStudyCase& c : cases) {
    const Stopwatch read_clock;
    LoadedCase l{c, {}, ct::read_nifti_labels(c.segmentation), 0.0};
    l.seconds_read = read_clock.seconds();
    l.reference = anatomy::import_mesh(c.reference, {.units = LengthUnit::kMm}).mesh;
    for (const Setting& s : settings) {
      const CtStudyRun r = run_once(l, s.voxel_factor, s.smoothing, s.adaptivity);
      csv << r.name << ',' << r.voxel_factor << ',' << r.smoothing << ',' << r.adaptivity << ',' << r.finest_voxel
          << ',' << r.seconds << ',' << r.triangles << ',' << (r.watertight ? 1 : 0) << ',' << r.genus << ','
          << r.volume_rel_err << ',' << r.mean_distance << ',' << r.rms_distance << ',' << r.max_distance << ','
          << r.trachea_diameter << ',' << r.deepest_generation << '\n';
      if (progress) progress(r);
    }
  }
  create_output_directory(dir);
  write_file_atomically(dir / "ct_study.csv", csv.str());
}

}  // namespace magvine::studies
