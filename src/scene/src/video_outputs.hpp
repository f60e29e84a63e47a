#pragma once
// The videos of outputs.video (render module), written by write_experiment_outputs. Private to the scene module and
// compiled only with MAGVINE_WITH_RENDER.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <vector>

#include "magvine/scene/experiment.hpp"

namespace magvine::scene {

/// What the overview shows that the scene and the result do not hold directly.
struct VideoInputs {
  std::vector<Vec3> planned_path;        ///< the navigator's [m]; empty without one
  std::vector<double> magnet_diameters;  ///< per magnet [m]; 0: a point dipole
  std::vector<double> magnet_lengths;    ///< [m]
};

/// Renders every video of scene.videos from result.frames into `dir` (atomically: each file, and each PNG folder,
/// appears complete or not at all) and returns the metrics.json entries [{camera, file, codec, frames, fps, size}].
nlohmann::json write_videos(const ExperimentScene& scene, const ExperimentResult& result, const VideoInputs& in,
                            const std::filesystem::path& dir);

}  // namespace magvine::scene
