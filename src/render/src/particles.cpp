#include "magvine/render/particles.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

namespace magvine::render {
namespace {

/// Image axes (right, up) and the depth axis (towards the viewer) of a view.
struct Axes {
  Vec3 right, up, towards;
};

Axes axes_of(const Vec3& direction, const Vec3& up) {
  const Vec3 d = direction.normalized();
  Vec3 u = up - up.dot(d) * d;
  if (u.norm() < 1e-9) u = d.unitOrthogonal();
  u.normalize();
  return {d.cross(u), u, -d};
}

// A palette that stays apart on white (BGR).
constexpr std::array<std::array<double, 3>, 8> kPalette{{{180, 119, 31},
                                                         {14, 127, 255},
                                                         {44, 160, 44},
                                                         {40, 39, 214},
                                                         {189, 103, 148},
                                                         {75, 86, 140},
                                                         {194, 119, 227},
                                                         {34, 189, 188}}};

}  // namespace

ParticleView frame_particles(const std::vector<std::vector<Vec3>>& frames, const Vec3& direction, const Vec3& up,
                             double aspect, double particle_radius) {
  const Axes a = axes_of(direction, up);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = Eigen::Vector2d::Constant(-1e300);
  Vec3 mean = Vec3::Zero();
  double n = 0.0;
  for (const auto& f : frames)
    for (const Vec3& p : f) {
      const Eigen::Vector2d q(p.dot(a.right), p.dot(a.up));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
      mean += p;
      n += 1.0;
    }
  ParticleView v;
  v.direction = direction;
  v.up = up;
  if (n == 0.0) return v;
  const Eigen::Vector2d mid = 0.5 * (lo + hi);
  const double depth = (mean / n).dot(a.towards);
  v.centre = mid.x() * a.right + mid.y() * a.up + depth * a.towards;
  const Eigen::Vector2d half = 0.5 * (hi - lo);
  v.half_height = 1.1 * std::max({half.y(), half.x() / aspect, 1e-6}) + 2.0 * particle_radius;
  v.radius = particle_radius;
  return v;
}

cv::Mat draw_particles(const std::vector<Vec3>& points, const std::vector<std::uint16_t>& body,
                       const ParticleView& view, int width, int height) {
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const Axes a = axes_of(view.direction, view.up);
  const double scale = 0.5 * height / view.half_height;  // px per metre
  std::vector<double> depth(points.size());
  double dmin = 1e300, dmax = -1e300;
  for (std::size_t i = 0; i < points.size(); ++i) {
    depth[i] = points[i].dot(a.towards);
    dmin = std::min(dmin, depth[i]);
    dmax = std::max(dmax, depth[i]);
  }
  std::vector<std::size_t> order(points.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return depth[i] < depth[j]; });
  const int r = std::max(1, static_cast<int>(std::lround(view.radius * scale)));
  for (const std::size_t i : order) {
    const Vec3 q = points[i] - view.centre;
    const cv::Point px(static_cast<int>(std::lround(0.5 * width + q.dot(a.right) * scale)),
                       static_cast<int>(std::lround(0.5 * height - q.dot(a.up) * scale)));
    const double near = dmax > dmin ? (depth[i] - dmin) / (dmax - dmin) : 1.0;  // 1 nearest
    const double shade = 0.55 + 0.45 * near;
    const auto& c = kPalette[body[i] % kPalette.size()];
    cv::circle(img, px, r, cv::Scalar(c[0] * shade, c[1] * shade, c[2] * shade), cv::FILLED, cv::LINE_AA);
  }
  return img;
}

}  // namespace magvine::render
