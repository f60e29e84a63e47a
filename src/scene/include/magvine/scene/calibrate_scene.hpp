#pragma once
/// Calibration files (`magvine calibrate CALIBRATE.yaml`, issue 29; format in docs/design.md#calibration): a
/// free-space vine scene as `magvine run` takes it, with one magnet where the approach starts, plus a `calibrate:`
/// section naming the uncertain parameters and a CSV of measurements; the outputs of a fit.

#include <filesystem>
#include <string>
#include <vector>

#include "magvine/design/calibration.hpp"
#include "magvine/scene/free_space.hpp"

namespace magvine::scene {

struct CalibrateScene {
  FreeSpaceScene scene;
  design::CalibrationProblem problem;
  int max_iterations = 50;
  /// Per parameter: its key under robot (e.g. "wall.youngs_modulus") and one file unit in SI (messages, outputs).
  std::vector<std::pair<std::string, double>> keys;
  std::vector<std::string> unit_names;  ///< per parameter: "kPa", "mm", "T", ""
  /// Per case: its diameter and pressure [SI] (the scene's unless the measurements name others).
  std::vector<std::pair<double, double>> case_settings;
  std::string file;
  std::string text;
  std::string measurements_file;
  double length_unit = 1e-3;
  double pressure_unit = 1.0;
};

/// Whether `file` is a calibration file (YAML with a top-level `calibrate:`); false for anything unreadable.
bool is_calibrate_scene(const std::filesystem::path& file);

/// Reads and checks a calibration file and its measurements; InputError (exit 2) naming the file, line and key.
CalibrateScene load_calibrate_scene(const std::filesystem::path& file);
/// The same from text; the measurements file is found relative to `directory`.
CalibrateScene parse_calibrate_scene(const std::string& text, const std::string& file_label,
                                     const std::filesystem::path& directory);

/// The scene with the fitted values in place of the parameters' (file units, 17 significant digits), without
/// `calibrate:`: `magvine run` takes it.
std::string calibrated_scene_yaml(const CalibrateScene& scene, const design::CalibrationResult& result);

/// Writes DIR/calibration.json (the parameters with their start, bounds, value and standard deviation in file
/// units; the covariance and correlation; χ², iterations, evaluations, equilibria, runtime, history), DIR/
/// predictions.csv (every measurement with the model's value and its standard deviation, fitted or held out, and its
/// z-score) and DIR/scene.yaml, each atomically (the folder is created).
void write_calibration_outputs(const CalibrateScene& scene, const design::CalibrationResult& result,
                               const std::filesystem::path& dir);

}  // namespace magvine::scene
