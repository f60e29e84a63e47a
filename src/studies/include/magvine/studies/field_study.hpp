#pragma once
/// Error-against-runtime study of the field models of one cylindrical magnet: the exact closed form, the point
/// dipole, and the surface quadrature at increasing resolution, all measured against a fine quadrature that
/// shares no code with the closed forms. Writes CSVs for tools/plot_field_models.py.

#include <filesystem>
#include <vector>

#include "magvine/magnetics/cylinder.hpp"

namespace magvine::studies {

struct FieldStudySpec {
  /// Distances from the magnet centre [m] at which the error is measured (19 polar angles 0–90° each, and the
  /// mirrored azimuth for transverse magnetisation).
  std::vector<double> distances{0.08, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3, 0.4};
};

/// Writes `dir/field_models.csv` (model,resolution,max_rel_err_B,ns_per_eval) and
/// `dir/field_model_distance.csv` (distance_m,dipole_err_B,dipole_err_G,exact_err_B), atomically.
/// Progress lines go to stderr.
void run_field_model_study(const magnetics::CylinderMagnet& magnet, const FieldStudySpec& spec,
                           const std::filesystem::path& dir);

}  // namespace magvine::studies
