#include "magvine/anatomy/mesh_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>

#include "magvine/core/disjoint_sets.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

// One use of an undirected edge by a triangle: key = (min vertex, max vertex), forward = the triangle runs
// min → max along it.
struct EdgeUse {
  std::uint64_t key;
  std::uint32_t triangle;
  bool forward;
  bool operator<(const EdgeUse& o) const { return key < o.key || (key == o.key && triangle < o.triangle); }
};

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
  return (static_cast<std::uint64_t>(lo) << 32) | hi;
}

// A boundary loop as a vertex cycle, directed as the triangles that own its edges run.
using Loop = std::vector<std::uint32_t>;

// Chains directed boundary edges (a → b) into closed loops. At pinch vertices (several boundary edges leave one
// vertex) any unused edge continues the walk, which still partitions the edges into closed cycles.
std::vector<Loop> trace_loops(std::vector<std::pair<std::uint32_t, std::uint32_t>> edges) {
  std::sort(edges.begin(), edges.end());
  std::vector<char> used(edges.size(), 0);
  auto first_from = [&](std::uint32_t a) {
    auto it = std::lower_bound(edges.begin(), edges.end(), std::make_pair(a, std::uint32_t{0}));
    for (; it != edges.end() && it->first == a; ++it) {
      const auto i = static_cast<std::size_t>(it - edges.begin());
      if (used[i] == 0) return i;
    }
    return edges.size();
  };
  std::vector<Loop> loops;
  for (std::size_t start = 0; start < edges.size(); ++start) {
    if (used[start] != 0) continue;
    Loop loop;
    std::size_t e = start;
    while (e < edges.size()) {
      used[e] = 1;
      loop.push_back(edges[e].first);
      if (edges[e].second == edges[start].first) break;
      e = first_from(edges[e].second);
    }
    loops.push_back(std::move(loop));
  }
  return loops;
}

}  // namespace

const char* to_string(Orientation orientation) {
  switch (orientation) {
    case Orientation::kOutward:
      return "outward";
    case Orientation::kInward:
      return "inward";
    case Orientation::kInconsistent:
      return "inconsistent";
    case Orientation::kUnknown:
      return "unknown";
  }
  return "unknown";
}

MeshReport analyse_mesh(const TriangleMesh& mesh) {
  MeshReport report;
  report.triangles = mesh.triangles.size();
  report.bbox = bounding_box(mesh);
  report.area = surface_area(mesh);
  std::vector<char> used_vertex(mesh.vertices.size(), 0);
  for (const Triangle& tri : mesh.triangles) {
    for (const std::uint32_t v : tri) used_vertex[v] = 1;
  }
  report.vertices = static_cast<std::size_t>(std::count(used_vertex.begin(), used_vertex.end(), 1));
  if (mesh.triangles.empty()) return report;

  // Edge table: sort all 3F edge uses so the uses of one edge are adjacent.
  std::vector<EdgeUse> uses;
  uses.reserve(3 * mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = tri[static_cast<std::size_t>(k)], b = tri[static_cast<std::size_t>((k + 1) % 3)];
      uses.push_back({edge_key(a, b), static_cast<std::uint32_t>(t), a < b});
    }
  }
  std::sort(uses.begin(), uses.end());

  DisjointSets sets(mesh.triangles.size());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> boundary;  // directed as in the owning triangle
  std::size_t edges = 0, misoriented = 0;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const std::size_t n = j - i;
    ++edges;
    for (std::size_t k = i + 1; k < j; ++k) sets.unite(uses[i].triangle, uses[k].triangle);
    if (n == 1) {
      const auto lo = static_cast<std::uint32_t>(uses[i].key >> 32), hi = static_cast<std::uint32_t>(uses[i].key);
      boundary.emplace_back(uses[i].forward ? lo : hi, uses[i].forward ? hi : lo);
    } else if (n == 2) {
      // A consistently oriented manifold edge is run once in each direction.
      if (uses[i].forward == uses[i + 1].forward) ++misoriented;
    } else {
      ++report.non_manifold_edges;
    }
    i = j;
  }
  report.boundary_edges = boundary.size();
  report.watertight = report.boundary_edges == 0 && report.non_manifold_edges == 0;

  std::vector<std::size_t> component_size(mesh.triangles.size(), 0);
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) ++component_size[sets.find(t)];
  report.components = static_cast<std::size_t>(
      std::count_if(component_size.begin(), component_size.end(), [](std::size_t s) { return s > 0; }));

  // Openings. Capping each loop with a fan to its centroid closes the surface, which gives the orientation of open
  // meshes too: the capped signed volume is positive for outward normals.
  const std::vector<Loop> loops = trace_loops(boundary);
  const Vec3 origin = mesh.vertices[mesh.triangles.front()[0]];
  double capped_six_volume = 6.0 * signed_volume(mesh);
  std::vector<Vec3> newell_vectors;
  for (const Loop& loop : loops) {
    Opening opening;
    opening.edges = loop.size();
    double perimeter = 0.0;
    Vec3 weighted = Vec3::Zero();
    for (std::size_t k = 0; k < loop.size(); ++k) {
      const Vec3& a = mesh.vertices[loop[k]];
      const Vec3& b = mesh.vertices[loop[(k + 1) % loop.size()]];
      const double length = (b - a).norm();
      perimeter += length;
      weighted += 0.5 * length * (a + b);
    }
    opening.centroid = perimeter > 0.0 ? Vec3(weighted / perimeter) : mesh.vertices[loop.front()];
    Vec3 newell = Vec3::Zero();
    for (std::size_t k = 0; k < loop.size(); ++k) {
      const Vec3 a = mesh.vertices[loop[k]] - opening.centroid;
      const Vec3 b = mesh.vertices[loop[(k + 1) % loop.size()]] - opening.centroid;
      newell += a.cross(b);
      // Cap triangle (centroid, b, a) runs the edge against the surface, as a closing face must.
      const Vec3 c = opening.centroid - origin, ao = mesh.vertices[loop[k]] - origin,
                 bo = mesh.vertices[loop[(k + 1) % loop.size()]] - origin;
      capped_six_volume += c.dot(bo.cross(ao));
    }
    opening.diameter = 2.0 * std::sqrt(0.5 * newell.norm() / kPi);
    newell_vectors.push_back(newell);
    report.openings.push_back(opening);
  }

  // Orientation: closed (or capped) signed volume sign, unless neighbours disagree.
  const double scale = std::pow(std::max((report.bbox.max - report.bbox.min).maxCoeff(), 1e-300), 3);
  if (misoriented > 0) {
    report.orientation = Orientation::kInconsistent;
  } else if (std::abs(capped_six_volume) > 1e-12 * scale) {
    report.orientation = capped_six_volume > 0.0 ? Orientation::kOutward : Orientation::kInward;
  }
  // An opening's normal points out of the mesh interior: against the loop's Newell vector for outward meshes.
  const double sign = report.orientation == Orientation::kInward ? 1.0 : -1.0;
  for (std::size_t k = 0; k < report.openings.size(); ++k) {
    const double n = newell_vectors[k].norm();
    if (n > 0.0) report.openings[k].normal = sign * newell_vectors[k] / n;
  }
  std::sort(report.openings.begin(), report.openings.end(),
            [](const Opening& a, const Opening& b) { return a.diameter > b.diameter; });

  if (report.watertight) report.volume = std::abs(signed_volume(mesh));

  // Genus from the Euler characteristic of an orientable surface with boundary: χ = V − E + F = 2C − 2g − B.
  const long chi = static_cast<long>(report.vertices) - static_cast<long>(edges) + static_cast<long>(report.triangles);
  report.genus = (2 * static_cast<long>(report.components) - static_cast<long>(loops.size()) - chi) / 2;

  // Warnings a user should act on.
  auto warn = [&report](const std::string& s) { report.warnings.push_back(s); };
  if (report.boundary_edges > 0) {
    warn("open mesh: " + std::to_string(report.boundary_edges) + " boundary edges in " + std::to_string(loops.size()) +
         " openings (cut airway ends are openings; the robot can leave through them)");
  }
  if (report.non_manifold_edges > 0) {
    warn(std::to_string(report.non_manifold_edges) +
         " non-manifold edges (shared by more than two triangles); "
         "genus and inside/outside tests are unreliable there");
  }
  if (misoriented > 0) {
    warn(std::to_string(misoriented) +
         " edges where neighbouring triangles have opposite winding; repair the "
         "normals (e.g. Slicer's Surface Toolbox) before use");
  }
  if (report.orientation == Orientation::kInward) warn("normals point into the lumen (inward-facing)");
  if (report.components > 1) {
    const std::size_t largest = *std::max_element(component_size.begin(), component_size.end());
    std::ostringstream s;
    s.precision(3);
    s << report.components << " connected components; the largest has "
      << 100.0 * static_cast<double>(largest) / static_cast<double>(report.triangles) << " % of the triangles";
    warn(s.str());
  }
  return report;
}

}  // namespace magvine::anatomy

namespace magvine::anatomy {
namespace {

nlohmann::json vec_json(const Vec3& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

std::string unit_label(LengthUnit units) {
  return units == LengthUnit::kMm ? "mm" : units == LengthUnit::kCm ? "cm" : "m";
}

}  // namespace

std::string report_json(const std::string& file, const ImportedMesh& imported, const MeshReport& report,
                        LengthUnit units) {
  nlohmann::json j;
  j["file"] = file;
  j["units"] = unit_label(units);
  j["triangles"] = report.triangles;
  j["vertices"] = report.vertices;
  j["raw_triangles"] = imported.stats.raw_triangles;
  j["raw_vertices"] = imported.stats.raw_vertices;
  j["bbox_min_m"] = vec_json(report.bbox.min);
  j["bbox_max_m"] = vec_json(report.bbox.max);
  j["area_m2"] = report.area;
  j["volume_m3"] = report.volume ? nlohmann::json(*report.volume) : nlohmann::json(nullptr);
  j["watertight"] = report.watertight;
  j["boundary_edges"] = report.boundary_edges;
  j["non_manifold_edges"] = report.non_manifold_edges;
  j["components"] = report.components;
  j["genus"] = report.genus;
  j["orientation"] = to_string(report.orientation);
  j["degenerate_removed"] = imported.stats.degenerate_removed;
  j["duplicate_removed"] = imported.stats.duplicate_removed;
  nlohmann::json openings = nlohmann::json::array();
  for (const Opening& o : report.openings) {
    openings.push_back(
        {{"centroid_m", vec_json(o.centroid)}, {"normal", vec_json(o.normal)}, {"diameter_m", o.diameter}});
  }
  j["openings"] = openings;
  nlohmann::json warnings = nlohmann::json::array();
  for (const std::string& w : imported.warnings) warnings.push_back(w);
  for (const std::string& w : report.warnings) warnings.push_back(w);
  j["warnings"] = warnings;
  return j.dump(2) + "\n";
}

std::string report_summary(const std::string& file, const ImportedMesh& imported, const MeshReport& report) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  const Vec3 size = (report.bbox.max - report.bbox.min) / kMmToM;
  s << file << "\n"
    << "  triangles   " << report.triangles << " (read " << imported.stats.raw_triangles << ", degenerate removed "
    << imported.stats.degenerate_removed << ", duplicates removed " << imported.stats.duplicate_removed << ")\n"
    << "  vertices    " << report.vertices << " (read " << imported.stats.raw_vertices << ")\n"
    << "  bounding box " << size.x() << " x " << size.y() << " x " << size.z() << " mm, from ("
    << report.bbox.min.x() / kMmToM << ", " << report.bbox.min.y() / kMmToM << ", " << report.bbox.min.z() / kMmToM
    << ") mm\n"
    << "  area        " << report.area / (kMmToM * kMmToM) << " mm^2\n";
  if (report.volume) {
    s << "  volume      " << *report.volume * 1e6 << " cm^3\n";
  } else {
    s << "  volume      - (not closed)\n";
  }
  s << "  watertight  " << (report.watertight ? "yes" : "no") << " (" << report.boundary_edges << " boundary, "
    << report.non_manifold_edges << " non-manifold edges)\n"
    << "  components  " << report.components << ", genus " << report.genus << ", normals "
    << to_string(report.orientation) << "\n"
    << "  openings    " << report.openings.size() << "\n";
  for (const Opening& o : report.openings) {
    s << "    diameter " << o.diameter / kMmToM << " mm at (" << o.centroid.x() / kMmToM << ", "
      << o.centroid.y() / kMmToM << ", " << o.centroid.z() / kMmToM << ") mm, normal (" << std::setprecision(3)
      << o.normal.x() << ", " << o.normal.y() << ", " << o.normal.z() << ")\n"
      << std::setprecision(1);
  }
  for (const std::string& w : imported.warnings) s << "  warning: " << w << "\n";
  for (const std::string& w : report.warnings) s << "  warning: " << w << "\n";
  return s.str();
}

}  // namespace magvine::anatomy
