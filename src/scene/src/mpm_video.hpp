#pragma once
// The MPM scene's particle video (render module only; without it write_mpm_video returns an empty path). Private to
// the scene module.

#include <cstdint>
#include <filesystem>
#include <vector>

#include "magvine/scene/mpm_scene.hpp"

namespace magvine::scene {

/// Writes `stem`.mp4 (or .avi) from the frames, one framing for all; returns the file, or {} without the render
/// module. `radius`: the particles' disc radius [m].
std::filesystem::path write_mpm_video(const MpmVideo& video, const std::vector<std::vector<Vec3>>& frames,
                                      const std::vector<std::uint16_t>& body, double radius,
                                      const std::filesystem::path& stem);

}  // namespace magvine::scene
