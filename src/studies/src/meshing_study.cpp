#include "magvine/studies/meshing_study.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "magvine/anatomy/implicit_surface.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/core/text.hpp"

namespace magvine::studies {

void run_meshing_study(const std::filesystem::path& dir) {
  std::string csv = "case,spacing_m,triangles,seconds,volume_rel_err,area_rel_err,max_surface_err_m\n";
  const double nan = std::numeric_limits<double>::quiet_NaN();

  // (a) A capsule of the size of a main bronchus (Ø12 mm, 40 mm between the cap centres), tilted off the grid axes
  // so no face lines up with the grid: exact volume πr²L + 4/3πr³, area 2πrL + 4πr², surface = zero set of its
  // exact distance function.
  const anatomy::RoundCone capsule{Vec3(0.0, 0.0, 0.0), Vec3(0.030, 0.017, 0.021), 6e-3, 6e-3};
  const double r = capsule.ra;
  const double length = (capsule.b - capsule.a).norm();
  const double volume = kPi * r * r * length + 4.0 / 3.0 * kPi * r * r * r;
  const double area = 2.0 * kPi * r * length + 4.0 * kPi * r * r;
  anatomy::CompositeSdf field;
  field.add_lumen(capsule, 0.0);
  for (const double h : {3e-3, 2e-3, 1.5e-3, 1e-3, 0.7e-3, 0.5e-3, 0.35e-3, 0.25e-3, 0.18e-3}) {
    const Stopwatch clock;
    const anatomy::TriangleMesh mesh = anatomy::mesh_implicit(field, {.spacing = h});
    const double seconds = clock.seconds();
    double surface = 0.0;
    for (const Vec3& v : mesh.vertices) surface = std::max(surface, std::abs(anatomy::signed_distance(capsule, v)));
    const double volume_err = std::abs(anatomy::signed_volume(mesh) - volume) / volume;
    const double area_err = std::abs(anatomy::surface_area(mesh) - area) / area;
    csv += "capsule,";
    append_csv_row(csv, std::array{h, static_cast<double>(mesh.triangles.size()), seconds, volume_err, area_err,
                                   surface});
    std::fprintf(stderr, "  capsule  h %.2f mm  %8zu triangles  %.3f s  volume %.2e  area %.2e  surface %.2e m\n",
                 h * 1e3, mesh.triangles.size(), seconds, volume_err, area_err, surface);
  }

  // (b) The default bronchial tree (generations 0–6) against itself at 0.22 mm. Spacings stay ≤ half the 1 mm
  // clearance, so every run has the same branch geometry and only the meshing differs.
  std::vector<std::array<double, 3>> tree;  // spacing, triangles, seconds
  std::vector<double> volumes;
  for (const double h : {0.5e-3, 0.45e-3, 0.4e-3, 0.35e-3, 0.3e-3, 0.26e-3, 0.22e-3}) {
    anatomy::BronchialTreeParams params;
    params.spacing = h;
    const Stopwatch clock;
    const anatomy::Phantom phantom = anatomy::make_bronchial_tree(params);
    const double seconds = clock.seconds();
    tree.push_back({h, static_cast<double>(phantom.mesh.triangles.size()), seconds});
    volumes.push_back(anatomy::signed_volume(phantom.mesh));
    std::fprintf(stderr, "  tree     h %.2f mm  %8zu triangles  %.3f s\n", h * 1e3, phantom.mesh.triangles.size(),
                 seconds);
  }
  for (std::size_t i = 0; i + 1 < tree.size(); ++i) {
    csv += "bronchial_tree,";
    append_csv_row(csv, std::array{tree[i][0], tree[i][1], tree[i][2],
                                   std::abs(volumes[i] - volumes.back()) / volumes.back(), nan, nan});
  }
  write_file_atomically(dir / "meshing_study.csv", csv);
}

}  // namespace magvine::studies
