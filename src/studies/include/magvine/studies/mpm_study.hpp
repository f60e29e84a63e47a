#pragma once
/// Validation and error-against-runtime study of the MPM solver on the Zhao beam (thesis 3.6.2; Zhao et al. 2019):
/// a 17.2 × 0.84 mm plane-strain cantilever (G 303 kPa, K = 20 G, Br 0.143 T along the beam) in a uniform field
/// antiparallel to its magnetisation. A 3 mT transverse kick for the first millisecond picks the buckled branch; the
/// tip deflection at rest is compared with Euler's elastica under the same load, in closed form:
///   √B̄ = K(k),  δ/L = 2k / K(k),  B̄ = 12 (L/t)² Br B / (μ0 E'),
/// E' = E/(1 − ν²) the plane-strain modulus of the Neo-Hookean's small-strain limit (E = 9KG/(3K + G)).

#include <cstddef>
#include <filesystem>
#include <functional>
#include <vector>

#include "magvine/mpm/mpm.hpp"

namespace magvine::studies {

/// Plane-strain Young's modulus E/(1 − ν²) of a material's small-strain limit [Pa].
double plane_strain_modulus(const mpm::Material& m);

/// Tip deflection δ/L of Euler's cantilever elastica under an axial dead load (the antiparallel field), B̄ > 0;
/// 0 below the buckling load B̄c = π²/4.
double antiparallel_elastica_deflection(double bbar);

/// One Zhao-beam run.
struct ZhaoPoint {
  int cells = 0;             ///< grid cells through the thickness
  int particles_per_cell = 0;  ///< per axis
  std::size_t particles = 0;
  double field = 0.0;        ///< |B| [T]
  double bbar = 0.0;
  double reference = 0.0;    ///< δ/L, elastica
  double deflection = 0.0;   ///< δ/L, MPM (|tip y| / L)
  bool settled = false;
  bool ok = true;
  long steps = 0;
  double seconds = 0.0;      ///< wall time of this run
};

/// Runs the beam at one resolution and field (single-threaded, to rest or 1.5 s simulated).
ZhaoPoint run_zhao_beam(int cells, int particles_per_cell, double field);

/// The fields of the study [T]: past the buckling field, up to a tip turned ~175°.
std::vector<double> zhao_study_fields();

/// Writes `dir/mpm_beam_study.csv` (one row per run) and `dir/mpm_beam_summary.csv` (per resolution: particles,
/// MAPE, total runtime) for tools/plot_mpm_study.py, atomically. Runs `jobs` beams at a time.
void run_mpm_beam_study(const std::filesystem::path& dir, int jobs,
                        const std::function<void(const ZhaoPoint&)>& progress = {});

}  // namespace magvine::studies
