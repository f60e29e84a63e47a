#pragma once
/// Cameras of the render module: a pinhole or an equidistant-fisheye lens at a pose, the ray through each pixel and
/// the pixel a direction lands on. Image x runs right and y down; pixel (i, j) covers [i, i+1) × [j, j+1) and its
/// centre is (i + ½, j + ½); the optical axis goes through the image centre (width/2, height/2).

#include <optional>

#include "magvine/core/eigen_types.hpp"

namespace magvine::render {

enum class Lens {
  kPinhole,   ///< r = f tan θ, f = (width/2) / tan(fov/2)
  kFisheye,   ///< equidistant: r = f θ, f = (width/2) / (fov/2); what wide endoscope lenses approximate
};

struct Camera {
  Vec3 position = Vec3::Zero();    ///< the lens [m]
  Vec3 forward = Vec3::UnitX();    ///< optical axis (normalised on use)
  Vec3 up = Vec3::UnitZ();         ///< the image's up direction; only its part across `forward` counts
  Lens lens = Lens::kFisheye;
  double fov = 1.9198621771937625; ///< full field of view across the image width [rad] (110°)
  int width = 320;                 ///< [px]
  int height = 320;                ///< [px]
};

/// The camera's orthonormal frame: columns right, down, forward (image x, image y, optical axis). InputError
/// ("camera") when forward is zero or parallel to up, or a number is not finite.
Mat3 camera_frame(const Camera& camera);

/// Focal length in pixels of the lens model (above). InputError for a field of view outside (0, 180°) for a
/// pinhole or (0, 360°) for a fisheye, or a size below 1 px.
double focal_pixels(const Camera& camera);

/// Unit ray direction, in the camera frame (x right, y down, z forward), through image point (px, py) [px].
Vec3 camera_ray(const Camera& camera, double focal, double px, double py);

/// The image point [px] where a world direction from the lens lands; nullopt when the lens cannot see it (behind a
/// pinhole, or beyond 180° from the axis for a fisheye). It may lie outside the image.
std::optional<Eigen::Vector2d> project_direction(const Camera& camera, const Vec3& world_direction);

}  // namespace magvine::render
