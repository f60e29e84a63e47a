#pragma once
/// Lumen detection in an endoscope frame: where the airway goes on, from the image alone (no depth, no pose).
///
/// The endoscope's light sits at the lens and falls off as 1/t² with range t (renderer.hpp), so a lumen seen along
/// its length is the darkest part of the frame and the wall near the lens the brightest: dark-region detection, the
/// classic cue of bronchoscope lumen tracking (Asari, Isoda & Toriwaki, Comput. Med. Imaging Graph. 2000; Sánchez et
/// al., "Navigation path retrieval from videobronchoscopy using bronchial branches", 2015, keep the dark blobs of a
/// multi-level threshold as the branches' openings). Here:
///   1. luminance, blurred (Gaussian, σ = blur × width), inside the image circle only (the inscribed circle: an
///      endoscope's picture is round, and the corners are dark from vignetting and the light cone's edge);
///   2. a reference level L95, the 95th percentile of the blurred luminance;
///   3. at each threshold fraction f in `levels`, the dark mask {pixel < f·L95}, split into connected components;
///      those of at least min_area of the image are lumens;
///   4. the level that shows the most lumens wins (ties: the lowest, whose blobs are the darkest cores, nearest the
///      far ends): two openings beyond a carina merge into one blob at a high level and vanish at a low one;
///   5. each lumen's centre is its darkness-weighted centroid (weights f·L95 − pixel), turned into a ray of the lens.
/// OpenCV does the image work (GaussianBlur, connectedComponentsWithStats).

#include <opencv2/core/mat.hpp>
#include <vector>

#include "magvine/render/camera.hpp"

namespace magvine::render {

struct LumenSettings {
  double blur = 0.02;                                ///< Gaussian σ as a fraction of the image width
  std::vector<double> levels{0.06, 0.12, 0.2, 0.3};  ///< threshold fractions of L95, ascending
  double min_area = 0.002;                           ///< smallest lumen, fraction of the image's pixels
};

/// One dark opening in the frame.
struct Lumen {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  ///< darkness-weighted centroid [px]
  Vec3 direction = Vec3::UnitZ();                   ///< its ray, camera frame (x right, y down, z forward)
  double area = 0.0;                                ///< fraction of the image
};

/// The lumens of a frame (CV_8UC3 BGR, as render_endoscope gives it) taken by `camera`, largest first; empty when
/// nothing is dark enough (the lens faces the wall). InputError for an empty or wrongly typed image, or settings out
/// of range (blur in (0, 0.5], levels ascending in (0, 1), min_area in (0, 1)).
std::vector<Lumen> detect_lumens(const cv::Mat& image, const Camera& camera,
                                 const LumenSettings& settings = LumenSettings{});

/// The frame with the lumens drawn (a ring at each centre, sized by its area; `chosen`, if ≥ 0, in green, the others
/// in yellow) for figures.
cv::Mat draw_lumens(const cv::Mat& image, const std::vector<Lumen>& lumens, int chosen);

}  // namespace magvine::render
