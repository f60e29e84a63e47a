#include "magvine/studies/centerline_study.hpp"

#include <array>
#include <cstdio>
#include <string>

#include "magvine/anatomy/centerline.hpp"
#include "magvine/anatomy/phantom.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/text.hpp"

namespace magvine::studies {

void run_centerline_study(const std::filesystem::path& dir) {
  std::string csv = "voxel_m,seconds,lumen_voxels,branches,reference_branches,same_topology,mean_distance_rel,"
                    "mean_radius_err,p95_radius_err,p95_radius_err_away\n";
  const anatomy::Phantom tree = anatomy::make_bronchial_tree({});
  for (const double h : {1.0e-3, 0.8e-3, 0.65e-3, 0.5e-3, 0.4e-3, 0.33e-3, 0.27e-3}) {
    anatomy::CenterlineOptions options;
    options.voxel = h;
    options.max_cells = 200'000'000;
    anatomy::CenterlineReport report;
    const anatomy::AirwayGraph graph = anatomy::extract_airway_graph(tree.mesh, options, &report);
    const anatomy::GraphComparison c = anatomy::compare_graphs(graph, tree.graph);
    append_csv_row(csv, std::array{h, report.seconds, static_cast<double>(report.inside_voxels),
                                   static_cast<double>(c.branches), static_cast<double>(c.reference_branches),
                                   c.same_topology ? 1.0 : 0.0, c.mean_distance, c.mean_radius_error,
                                   c.p95_radius_error, c.p95_radius_error_away});
    std::fprintf(stderr, "  voxel %.2f mm  %8zu voxels  %6.2f s  %3zu/%3zu branches%s  distance %5.1f %%  radius %5.1f %% (p95 %5.1f %%, away from junctions %4.1f %%)\n",
                 1e3 * h, report.inside_voxels, report.seconds, c.branches, c.reference_branches,
                 c.same_topology ? " (exact)" : "", 100 * c.mean_distance, 100 * c.mean_radius_error,
                 100 * c.p95_radius_error, 100 * c.p95_radius_error_away);
  }
  write_file_atomically(dir / "centerline_study.csv", csv);
}

}  // namespace magvine::studies
