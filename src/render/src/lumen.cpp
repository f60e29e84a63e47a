#include "magvine/render/lumen.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::render {

namespace {

void check(const cv::Mat& image, const LumenSettings& s) {
  if (image.empty() || image.type() != CV_8UC3) {
    throw InputError("lumen detection", 0, "image", "needs a non-empty 8-bit BGR frame");
  }
  if (!(s.blur > 0.0 && s.blur <= 0.5)) throw InputError("lumen detection", 0, "blur", "must lie in (0, 0.5]");
  if (s.levels.empty()) throw InputError("lumen detection", 0, "levels", "needs at least one threshold");
  for (std::size_t k = 0; k < s.levels.size(); ++k) {
    const double f = s.levels[k];
    if (!(f > 0.0 && f < 1.0)) throw InputError("lumen detection", 0, "levels", "each must lie in (0, 1)");
    if (k > 0 && !(f > s.levels[k - 1])) throw InputError("lumen detection", 0, "levels", "must ascend");
  }
  if (!(s.min_area > 0.0 && s.min_area < 1.0)) {
    throw InputError("lumen detection", 0, "min_area", "must lie in (0, 1)");
  }
}

/// The lumens of the mask {grey < level} (step 3 and 5 of lumen.hpp).
std::vector<Lumen> lumens_below(const cv::Mat& grey, float level, const Camera& camera, double focal, double min_area) {
  cv::Mat mask = grey < level;
  cv::Mat labels;
  cv::Mat stats;
  cv::Mat centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  const double pixels = static_cast<double>(grey.total());
  std::vector<double> weight(static_cast<std::size_t>(n), 0.0);
  std::vector<double> sx(static_cast<std::size_t>(n), 0.0);
  std::vector<double> sy(static_cast<std::size_t>(n), 0.0);
  for (int y = 0; y < grey.rows; ++y) {
    const auto* g = grey.ptr<float>(y);
    const auto* l = labels.ptr<int>(y);
    for (int x = 0; x < grey.cols; ++x) {
      if (l[x] == 0) continue;
      const double w = level - g[x];
      const auto k = static_cast<std::size_t>(l[x]);
      weight[k] += w;
      sx[k] += w * (x + 0.5);
      sy[k] += w * (y + 0.5);
    }
  }
  std::vector<Lumen> out;
  for (int k = 1; k < n; ++k) {
    const double area = stats.at<int>(k, cv::CC_STAT_AREA) / pixels;
    const auto i = static_cast<std::size_t>(k);
    if (area < min_area || weight[i] <= 0.0) continue;
    Lumen lumen;
    lumen.pixel = Eigen::Vector2d(sx[i] / weight[i], sy[i] / weight[i]);
    lumen.direction = camera_ray(camera, focal, lumen.pixel.x(), lumen.pixel.y());
    lumen.area = area;
    out.push_back(lumen);
  }
  std::sort(out.begin(), out.end(), [](const Lumen& a, const Lumen& b) { return a.area > b.area; });
  return out;
}

}  // namespace

std::vector<Lumen> detect_lumens(const cv::Mat& image, const Camera& camera, const LumenSettings& settings) {
  check(image, settings);
  const double focal = focal_pixels(camera);
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(grey, CV_32F);
  const double sigma = std::max(0.5, settings.blur * image.cols);
  cv::GaussianBlur(grey, grey, cv::Size(0, 0), sigma);
  // Only the image circle counts (an endoscope's picture is round): the corners, darkened by vignetting and the
  // light's fall-off at the edge of its cone, are set bright.
  cv::Mat outside(grey.size(), CV_8U, cv::Scalar(255));
  cv::circle(outside, cv::Point(grey.cols / 2, grey.rows / 2), std::min(grey.cols, grey.rows) / 2, cv::Scalar(0),
             cv::FILLED);
  std::vector<float> values;
  for (int y = 0; y < grey.rows; ++y) {
    for (int x = 0; x < grey.cols; ++x) {
      if (outside.at<std::uint8_t>(y, x) == 0) values.push_back(grey.at<float>(y, x));
    }
  }
  if (values.empty()) return {};
  // L95: the 95th percentile of the blurred luminance in the circle.
  const auto at = values.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), at, values.end());
  const double l95 = *at;
  std::vector<Lumen> best;
  if (l95 <= 0.0) return best;
  grey.setTo(cv::Scalar(2.0 * l95), outside);  // a black frame: nothing to tell the lumen from
  for (const double f : settings.levels) {
    std::vector<Lumen> found = lumens_below(grey, static_cast<float>(f * l95), camera, focal, settings.min_area);
    if (found.size() > best.size()) best = std::move(found);
  }
  return best;
}

cv::Mat draw_lumens(const cv::Mat& image, const std::vector<Lumen>& lumens, int chosen) {
  cv::Mat out = image.clone();
  const double pixels = static_cast<double>(image.total());
  for (std::size_t k = 0; k < lumens.size(); ++k) {
    const Lumen& l = lumens[k];
    const cv::Point centre(static_cast<int>(std::lround(l.pixel.x())), static_cast<int>(std::lround(l.pixel.y())));
    const int radius = std::max(4, static_cast<int>(std::lround(std::sqrt(l.area * pixels / kPi))));
    const cv::Scalar colour = static_cast<int>(k) == chosen ? cv::Scalar(60, 220, 60) : cv::Scalar(40, 220, 240);
    cv::circle(out, centre, radius, colour, 2, cv::LINE_AA);
    cv::drawMarker(out, centre, colour, cv::MARKER_CROSS, 8, 2, cv::LINE_AA);
  }
  return out;
}

}  // namespace magvine::render
