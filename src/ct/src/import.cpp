#include "magvine/ct/import.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "magvine/anatomy/collision_world.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"

namespace magvine::ct {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// ImportResult::trachea_lr, trachea_ap and trachea_diameter: rays from the middle half of the root branch's nodes,
/// across the branch, in 32 directions starting from the world x axis (left–right in RAS and LPS).
void trachea_widths(const anatomy::CollisionWorld& world, const anatomy::AirwayGraph& graph, ImportResult& result) {
  if (graph.branches.empty() || graph.branches.front().nodes.size() < 4) return;
  constexpr int kRays = 32;
  const std::vector<std::uint32_t>& nodes = graph.branches.front().nodes;
  std::vector<double> lr, ap, diameter;
  for (std::size_t n = nodes.size() / 4; n < nodes.size() - nodes.size() / 4; ++n) {
    const Vec3 p = graph.nodes[nodes[n]].position;
    const Vec3 t = (graph.nodes[nodes[std::min(n + 1, nodes.size() - 1)]].position -
                    graph.nodes[nodes[n > 0 ? n - 1 : 0]].position)
                       .normalized();
    const Vec3 x = (Vec3::UnitX() - Vec3::UnitX().dot(t) * t).normalized();
    const Vec3 y = t.cross(x);
    std::array<double, kRays> reach{};
    bool closed = true;
    for (int k = 0; k < kRays && closed; ++k) {
      const double a = 2.0 * std::numbers::pi * k / kRays;
      const auto hit = world.ray_cast(p, std::cos(a) * x + std::sin(a) * y, 0.1);
      closed = hit.has_value();
      if (closed) reach[static_cast<std::size_t>(k)] = hit->distance;
    }
    if (!closed) continue;
    double area = 0.0;
    for (int k = 0; k < kRays; ++k) {
      area += 0.5 * reach[static_cast<std::size_t>(k)] * reach[static_cast<std::size_t>((k + 1) % kRays)] *
              std::sin(2.0 * std::numbers::pi / kRays);
    }
    lr.push_back(reach[0] + reach[kRays / 2]);
    ap.push_back(reach[kRays / 4] + reach[3 * kRays / 4]);
    diameter.push_back(2.0 * std::sqrt(area / std::numbers::pi));
  }
  result.trachea_lr = median(lr);
  result.trachea_ap = median(ap);
  result.trachea_diameter = median(diameter);
}

/// Everything after the surface: read back from `stl`, analysed, graph extracted, collision world built.
void analyse(const std::filesystem::path& stl, const ImportOptions& options, ImportResult& result) {
  const Stopwatch report_clock;
  result.mesh = anatomy::import_mesh(stl, {.units = LengthUnit::kMm});
  result.report = anatomy::analyse_mesh(result.mesh.mesh);
  result.seconds_report = report_clock.seconds();
  const Stopwatch graph_clock;
  result.graph = anatomy::extract_airway_graph(result.mesh.mesh, options.graph, &result.graph_report);
  result.seconds_graph = graph_clock.seconds();
  result.world.emplace(result.mesh.mesh);
  trachea_widths(*result.world, result.graph, result);
  for (const auto& b : result.graph.branches)
    result.deepest_generation = std::max(result.deepest_generation, b.generation);
}

/// A scratch path in `dir` for a file that is renamed into place at the end.
std::filesystem::path scratch(const std::filesystem::path& dir, const std::string& name) {
  return dir / (".partial-" + std::to_string(::getpid()) + "-" + name);
}

/// Removes the listed files unless released (a failed import leaves nothing behind).
struct Cleanup {
  std::vector<std::filesystem::path> files;
  bool released = false;
  ~Cleanup() {
    if (released) return;
    std::error_code ec;
    for (const auto& f : files) std::filesystem::remove(f, ec);
  }
};

}  // namespace

ImportResult import_anatomy(const LabelVolume& volume, const std::string& file, const ImportOptions& options) {
  const Stopwatch clock;
  ImportResult result;
  const anatomy::TriangleMesh surface = segmentation_surface(volume, options.surface, file, &result.surface);
  // Through an STL in the temporary folder, so that the mesh is the one DIR/airway.stl would give.
  static std::atomic<unsigned> serial{0};
  const std::filesystem::path stl =
      std::filesystem::temp_directory_path() /
      ("magvine-ct-" + std::to_string(::getpid()) + "-" + std::to_string(serial++) + ".stl");
  Cleanup cleanup{{stl}};
  anatomy::write_stl(stl, surface);
  analyse(stl, options, result);
  result.seconds_total = clock.seconds();
  return result;
}

ImportResult import_anatomy(const std::filesystem::path& file, const ImportOptions& options) {
  const Stopwatch clock;
  const LabelVolume volume = read_nifti_labels(file);
  const double read = clock.seconds();
  ImportResult result = import_anatomy(volume, file.string(), options);
  result.surface.seconds_read = read;
  result.seconds_total = clock.seconds();
  return result;
}

ImportResult import_to_folder(const std::filesystem::path& file, const std::filesystem::path& dir,
                              const ImportOptions& options) {
  const Stopwatch clock;
  ImportResult result;
  // All the work that can fail on the input happens before the folder is touched.
  const anatomy::TriangleMesh surface = import_segmentation(file, options.surface, &result.surface);
  create_output_directory(dir);
  const std::filesystem::path stl = dir / "airway.stl";
  const std::filesystem::path stl_scratch = scratch(dir, "airway.stl");
  const std::filesystem::path graph_scratch = scratch(dir, "graph.json");
  Cleanup cleanup{{stl_scratch, graph_scratch}};
  anatomy::write_stl(stl_scratch, surface);
  analyse(stl_scratch, options, result);
  anatomy::write_graph(graph_scratch, result.graph);
  result.seconds_total = clock.seconds();
  const std::string report = anatomy::report_json(stl.string(), result.mesh, result.report, LengthUnit::kMm);
  const std::string summary = import_json(file.string(), options, result);
  std::filesystem::rename(stl_scratch, stl);
  std::filesystem::rename(graph_scratch, dir / "graph.json");
  write_file_atomically(dir / "report.json", report);
  write_file_atomically(dir / "import.json", summary);
  cleanup.released = true;
  return result;
}

std::string import_json(const std::string& file, const ImportOptions& options, const ImportResult& r) {
  const SurfaceReport& s = r.surface;
  nlohmann::ordered_json j;
  j["file"] = file;
  j["label"] = options.surface.label;
  j["frame"] = options.surface.frame == Frame::kLps ? "LPS" : "RAS";
  j["frame_source"] = s.frame_source;
  j["dims"] = s.dims;
  j["spacing_mm"] = {1e3 * s.spacing[0], 1e3 * s.spacing[1], 1e3 * s.spacing[2]};
  j["obliquity_deg"] = s.obliquity_deg;
  j["level_set_voxel_mm"] = 1e3 * s.voxel;
  j["smoothing"] = options.surface.smoothing;
  j["adaptivity"] = options.surface.adaptivity;
  j["label_voxels"] = s.label_voxels;
  j["components"] = s.components;
  j["notes"] = s.notes;
  j["warnings"] = s.warnings;
  j["triangles"] = r.report.triangles;
  j["watertight"] = r.report.watertight;
  j["genus"] = r.report.genus;
  j["volume_cm3"] = r.report.volume ? nlohmann::ordered_json(1e6 * *r.report.volume) : nlohmann::ordered_json();
  j["trachea_diameter_mm"] = 1e3 * r.trachea_diameter;
  j["trachea_lr_mm"] = 1e3 * r.trachea_lr;
  j["trachea_ap_mm"] = 1e3 * r.trachea_ap;
  j["branches"] = r.graph.branches.size();
  j["deepest_generation"] = r.deepest_generation;
  j["seconds"] = {{"read", s.seconds_read},
                  {"surface", s.seconds_surface},
                  {"report", r.seconds_report},
                  {"graph", r.seconds_graph},
                  {"total", r.seconds_total}};
  return j.dump(2) + "\n";
}

std::string import_summary(const std::string& file, const ImportResult& r) {
  const SurfaceReport& s = r.surface;
  std::ostringstream o;
  o.precision(4);
  o << file << ": " << s.dims[0] << " x " << s.dims[1] << " x " << s.dims[2] << " voxels of " << 1e3 * s.spacing[0]
    << " x " << 1e3 * s.spacing[1] << " x " << 1e3 * s.spacing[2] << " mm (" << s.frame_source << "), "
    << s.label_voxels << " in the label, " << s.components.size() << " component(s)\n";
  o << "  surface  " << r.report.triangles << " triangles, " << (r.report.watertight ? "watertight" : "NOT watertight")
    << ", genus " << r.report.genus << ", volume " << (r.report.volume ? 1e6 * *r.report.volume : 0.0) << " cm^3\n";
  o << "  graph    " << r.graph.branches.size() << " branches, generations 0-" << r.deepest_generation << ", trachea "
    << 1e3 * r.trachea_diameter << " mm across (area-equivalent; " << 1e3 * r.trachea_lr << " left-right, "
    << 1e3 * r.trachea_ap << " front-back)\n";
  o << "  time     " << r.seconds_total << " s (read " << s.seconds_read << ", surface " << s.seconds_surface
    << ", report " << r.seconds_report << ", graph " << r.seconds_graph << ")\n";
  return o.str();
}

}  // namespace magvine::ct
