#pragma once
/// Free-space robot scenes: one rod or vine clamped at its base, magnets, gravity, solved to static equilibrium by
/// `magvine run`. The file format is documented once, in docs/scenes.md (free-space scenes); errors are InputError
/// (exit 2): file, line, key path and what is wrong, every number checked against its plausible range.

#include <filesystem>
#include <optional>
#include <string>

#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::scene {

struct FreeSpaceScene {
  robot::RodModel model;                         ///< SI, base pose and gravity set
  std::optional<robot::VineParameters> vine;     ///< the vine's parameters (kind vine; none: a rod)
  std::optional<magnetics::FieldModel> magnets;  ///< none: no field evaluated at all
  robot::RodSolveOptions solver;

  /// "vine" or "rod", as in the file and metrics.json.
  const char* kind() const { return vine ? "vine" : "rod"; }
};

FreeSpaceScene load_free_space_scene(const std::filesystem::path& file);
FreeSpaceScene parse_free_space_scene(const std::string& text, const std::string& file_label);

/// The outcome of a run, SI.
struct FreeSpaceResult {
  robot::RodState state;
  robot::RodSolveReport report;
  double runtime_s = 0.0;
};

/// Solves the scene to static equilibrium from the straight body.
FreeSpaceResult solve_free_space(const FreeSpaceScene& scene);

/// Writes `dir/metrics.json` and `dir/shape.csv` atomically (the folder is created). metrics.json keys:
/// tip_position_m, tip_tangent, bend_angle_deg, converged, iterations, runtime_s, and load_steps, nodes,
/// gradient_norm, failure, max_bending_moment_Nm; a vine adds pressure_Pa, pressure_radius_m (its radius with the
/// diametric extension), axial_tension_N (= PπR², the tip force of the pressure), wrinkling_moment_Nm,
/// collapse_moment_Nm, wrinkled_length_m and creased.
void write_free_space_outputs(const FreeSpaceScene& scene, const FreeSpaceResult& result,
                              const std::filesystem::path& dir);

}  // namespace magvine::scene
