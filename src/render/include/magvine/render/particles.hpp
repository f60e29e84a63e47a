#pragma once
/// Pictures of particle sets (MPM snapshots): an orthographic view along a direction, each particle a disc coloured by
/// its body and shaded by depth (nearer is brighter), drawn far to near. One framing for a whole sequence, so a video
/// does not zoom.

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::render {

/// The view: looking along `direction` with `up` towards the image's top; `centre` and `half_height` [m] frame it.
struct ParticleView {
  Vec3 direction = -Vec3::UnitY();
  Vec3 up = Vec3::UnitZ();
  Vec3 centre = Vec3::Zero();
  double half_height = 0.01;
  double radius = 0.0;  ///< disc radius [m]; 0: half the median spacing guess (set by frame_particles)
};

/// A view along `direction`/`up` that holds every point of every frame with a 10 % margin at the given aspect ratio.
ParticleView frame_particles(const std::vector<std::vector<Vec3>>& frames, const Vec3& direction, const Vec3& up,
                             double aspect, double particle_radius);

/// A BGR image of `points` (body[i] picks the colour) on a white background.
cv::Mat draw_particles(const std::vector<Vec3>& points, const std::vector<std::uint16_t>& body,
                       const ParticleView& view, int width, int height);

}  // namespace magvine::render
