#pragma once
/// Free-space robot scenes (issue 4; the scenes issue extends the format): one rod or vine clamped at its base,
/// magnets, gravity, solved to static equilibrium by `magvine run`.
///
/// ```yaml
/// units: {length: mm, pressure: kPa}   # length: mm | cm | m (required); pressure: Pa | kPa | MPa (default Pa),
///                                      # for every stress: moduli, pressure, strength. Br and fields in tesla,
///                                      # density kg/m³, gravity m/s².
/// robot:
///   kind: rod
///   length: 60
///   section: {shape: rectangle, width: 3, thickness: 3}   # or {shape: circle, diameter: 2}; thickness ∥ base normal
///   shear_modulus: 120000              # or youngs_modulus (E = 3G, incompressible)
///   density: 1882
///   magnetisation:                     # optional; sections from the base, remanence [T], direction in the body frame
///     - {from: 0, to: 60, remanence: 0.125, direction: [1, 0, 0]}   # x = tangent, y = base normal, z = x × y
///   base: {position: [0, 0, 0], direction: [1, 0, 0], normal: [0, 1, 0]}   # clamped here
///   nodes: 51                          # optional (default 51); or node_spacing (length units)
/// magnets:                             # optional; entries as in the magnets file
///   - {kind: uniform, field: [0, 0.01, 0]}
/// simulation: {gravity: [0, -9.81, 0]} # optional; also tolerance (scaled gradient), max_load_steps
/// ```
/// A vine replaces section/modulus/density/magnetisation with
/// ```yaml
///   kind: vine
///   length: 80
///   diameter: 8
///   pressure: 12
///   wall: {thickness: 0.02, youngs_modulus: 200000, density: 920, strength: 10000}   # strength optional
///   skin: {thickness: 0.2, youngs_modulus: 99, density: 1840, remanence: 0.101, direction: [0, 1, 0]}  # optional
///   fill: {kind: magnetic_fluid, volume_fraction: 0.23, law: bounded}   # air (default) | water | magnetic_fluid;
///                                                                        # law: bounded (default) | thesis
/// ```
/// Errors (InputError, exit 2): file, line, key path and what is wrong; unknown keys name the closest valid one.

#include <filesystem>
#include <optional>
#include <string>

#include "magvine/magnetics/field_model.hpp"
#include "magvine/robot/rod.hpp"
#include "magvine/robot/vine.hpp"

namespace magvine::scene {

struct FreeSpaceScene {
  std::string kind;                             ///< "rod" | "vine"
  robot::RodModel model;                        ///< SI, base pose and gravity set
  std::optional<robot::VineParameters> vine;    ///< the vine's parameters (kind vine)
  std::optional<magnetics::FieldModel> magnets; ///< none: no field evaluated at all
  robot::RodSolveOptions solver;
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
/// gradient_norm, failure, max_bending_moment_Nm; a vine adds pressure_Pa, axial_tension_N (= PπR², the tip force
/// of the pressure), wrinkling_moment_Nm, collapse_moment_Nm, wrinkled_length_m and creased.
void write_free_space_outputs(const FreeSpaceScene& scene, const FreeSpaceResult& result,
                              const std::filesystem::path& dir);

}  // namespace magvine::scene
