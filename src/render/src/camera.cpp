#include "magvine/render/camera.hpp"

#include <cmath>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::render {

Mat3 camera_frame(const Camera& camera) {
  if (!camera.position.allFinite() || !camera.forward.allFinite() || !camera.up.allFinite()) {
    throw InputError("camera", 0, "", "a camera position or direction is not finite");
  }
  const double f_norm = camera.forward.norm();
  if (f_norm == 0.0) throw InputError("camera", 0, "forward", "the viewing direction is zero");
  const Vec3 forward = camera.forward / f_norm;
  const Vec3 across = camera.up - camera.up.dot(forward) * forward;
  if (across.norm() <= 1e-9 * std::max(1.0, camera.up.norm())) {
    throw InputError("camera", 0, "up", "the up direction is zero or parallel to the viewing direction");
  }
  const Vec3 up = across.normalized();
  Mat3 frame;
  frame.col(0) = forward.cross(up);  // right (looking along +x with z up, right is −y)
  frame.col(1) = -up;                // image y runs down
  frame.col(2) = forward;
  return frame;
}

double focal_pixels(const Camera& camera) {
  if (camera.width < 1 || camera.height < 1) {
    throw InputError("camera", 0, "size", "the image size must be at least 1 × 1 px");
  }
  const double half = 0.5 * camera.fov;
  if (camera.lens == Lens::kPinhole) {
    if (!(camera.fov > 0.0 && camera.fov < kPi)) {
      throw InputError("camera", 0, "fov", "a pinhole's field of view must lie in (0, 180) degrees");
    }
    return 0.5 * camera.width / std::tan(half);
  }
  if (!(camera.fov > 0.0 && camera.fov < 2.0 * kPi)) {
    throw InputError("camera", 0, "fov", "a fisheye's field of view must lie in (0, 360) degrees");
  }
  return 0.5 * camera.width / half;
}

Vec3 camera_ray(const Camera& camera, double focal, double px, double py) {
  const double a = (px - 0.5 * camera.width) / focal;
  const double b = (py - 0.5 * camera.height) / focal;
  if (camera.lens == Lens::kPinhole) return Vec3(a, b, 1.0).normalized();
  const double theta = std::hypot(a, b);  // equidistant: the distance from the centre is the angle
  if (theta < 1e-12) return Vec3::UnitZ();
  const double s = std::sin(theta) / theta;
  return Vec3(a * s, b * s, std::cos(theta));
}

std::optional<Eigen::Vector2d> project_direction(const Camera& camera, const Vec3& world_direction) {
  const Mat3 frame = camera_frame(camera);
  const double focal = focal_pixels(camera);
  const Vec3 d = frame.transpose() * world_direction;
  const Eigen::Vector2d centre(0.5 * camera.width, 0.5 * camera.height);
  if (camera.lens == Lens::kPinhole) {
    if (d.z() <= 0.0) return std::nullopt;
    return centre + focal * Eigen::Vector2d(d.x() / d.z(), d.y() / d.z());
  }
  const double rho = std::hypot(d.x(), d.y());
  if (rho < 1e-15 * d.norm()) {
    if (d.z() > 0.0) return centre;
    return std::nullopt;  // straight behind: every point of the 180° circle
  }
  const double theta = std::atan2(rho, d.z());
  return centre + focal * theta / rho * Eigen::Vector2d(d.x(), d.y());
}

}  // namespace magvine::render
