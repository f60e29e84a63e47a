// Render module: lens geometry against closed forms, the endoscope's view of a straight tube against the tube's
// analytic depth and symmetry, video and image files read back, the bronchial phantom's exposure, determinism.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <span>
#include <vector>

#include "magvine/anatomy/phantom.hpp"
#include "magvine/anatomy/primitives.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/render/camera.hpp"
#include "magvine/render/lumen.hpp"
#include "magvine/render/renderer.hpp"
#include "magvine/render/video.hpp"

namespace magvine::render {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("magvine_test_render_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// A UV sphere of radius r at c, outward normals.
anatomy::TriangleMesh ball(const Vec3& c, double r, int n = 24) {
  anatomy::TriangleMesh m;
  for (int i = 0; i <= n; ++i) {
    const double th = kPi * i / n;
    for (int j = 0; j < 2 * n; ++j) {
      const double ph = kPi * j / n;
      m.vertices.push_back(c + r * Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  }
  const auto at = [n](int i, int j) { return static_cast<std::uint32_t>(i * 2 * n + (j % (2 * n))); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 2 * n; ++j) {
      m.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return m;
}

double grey(const cv::Mat& img, double x, double y) {  // mean of a 3 × 3 patch, all channels
  double s = 0.0;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const cv::Vec3b p = img.at<cv::Vec3b>(static_cast<int>(y) + dy, static_cast<int>(x) + dx);
      s += (p[0] + p[1] + p[2]) / 3.0;
    }
  }
  return s / 9.0;
}

TEST(Camera, FisheyeMapsAKnownDirectionToItsPixel) {
  // Equidistant lens: r = f θ with f = (W/2)/(fov/2). 120° over 320 px: f = 160/(π/3) = 152.789 px.
  Camera cam;
  cam.lens = Lens::kFisheye;
  cam.fov = 120.0 * kDegToRad;
  cam.forward = Vec3::UnitX();
  cam.up = Vec3::UnitZ();
  const double f = 160.0 / (kPi / 3.0);
  EXPECT_NEAR(focal_pixels(cam), f, 1e-12);
  // 45° to the right (−y when looking along +x with z up): x = 160 + f π/4, y = 160.
  const auto right = project_direction(cam, Vec3(1.0, -1.0, 0.0));
  ASSERT_TRUE(right);
  EXPECT_NEAR(right->x(), 160.0 + f * kPi / 4.0, 1e-9);
  EXPECT_NEAR(right->y(), 160.0, 1e-9);
  // 30° up and 100° off-axis (beyond a pinhole's reach) land at r = f θ along their azimuth.
  const auto up = project_direction(cam, Vec3(std::cos(0.5236), 0.0, std::sin(0.5236)));
  ASSERT_TRUE(up);
  EXPECT_NEAR(up->y(), 160.0 - f * 0.5236, 1e-9);
  const double th = 100.0 * kDegToRad;
  const auto wide = project_direction(cam, Vec3(std::cos(th), 0.0, -std::sin(th)));
  ASSERT_TRUE(wide);
  EXPECT_NEAR(wide->y(), 160.0 + f * th, 1e-9);
  // The ray through that pixel is the direction again.
  const Vec3 back = camera_frame(cam) * camera_ray(cam, f, wide->x(), wide->y());
  EXPECT_LT((back - Vec3(std::cos(th), 0.0, -std::sin(th))).norm(), 1e-12);
}

TEST(Camera, PinholeProjectsByTheTangent) {
  Camera cam;
  cam.lens = Lens::kPinhole;
  cam.fov = 90.0 * kDegToRad;
  cam.width = 400;
  cam.height = 300;
  const double f = 200.0;  // (W/2) / tan 45°
  EXPECT_NEAR(focal_pixels(cam), f, 1e-9);
  const auto p = project_direction(cam, Vec3(1.0, -0.3, 0.2));
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->x(), 200.0 + f * 0.3, 1e-9);
  EXPECT_NEAR(p->y(), 150.0 - f * 0.2, 1e-9);
  EXPECT_FALSE(project_direction(cam, Vec3(-1.0, 0.0, 0.0)));
  cam.fov = kPi;
  EXPECT_THROW(focal_pixels(cam), InputError);
}

TEST(Endoscope, ARenderedBallLandsWhereTheLensModelPutsIt) {
  // A 1 mm ball 50 mm away, 45° right and 20° up of the axis: the centroid of its hit pixels is the projection of
  // its centre. The silhouette of a ball is symmetric about its centre's ray to first order; the residue at this
  // size (the ball spans ~3 px) is well under half a pixel.
  const double az = 45.0 * kDegToRad;
  const double el = 20.0 * kDegToRad;
  const Vec3 dir(std::cos(el) * std::cos(az), -std::cos(el) * std::sin(az), std::sin(el));
  const AirwayRenderer renderer(ball(0.05 * dir, 1e-3));
  for (const Lens lens : {Lens::kFisheye, Lens::kPinhole}) {
    Camera cam;
    cam.lens = lens;
    cam.fov = 130.0 * kDegToRad;
    const EndoscopeFrame f = renderer.render_endoscope(cam, EndoscopeLook{});
    double sx = 0.0, sy = 0.0, n = 0.0;
    for (int y = 0; y < f.depth.rows; ++y) {
      for (int x = 0; x < f.depth.cols; ++x) {
        if (f.depth.at<float>(y, x) > 0.0f) {
          sx += x + 0.5;
          sy += y + 0.5;
          n += 1.0;
        }
      }
    }
    ASSERT_GT(n, 3.0);
    const auto expected = project_direction(cam, dir);
    ASSERT_TRUE(expected);
    EXPECT_NEAR(sx / n, expected->x(), 0.5) << (lens == Lens::kFisheye ? "fisheye" : "pinhole");
    EXPECT_NEAR(sy / n, expected->y(), 0.5) << (lens == Lens::kFisheye ? "fisheye" : "pinhole");
  }
}

class TubeView : public ::testing::Test {
 protected:
  // A Ø10 mm tube along +z, 100 mm long, capped; the camera on its axis 10 mm in, looking down it.
  static constexpr double kRadius = 5e-3;
  static constexpr int kSegments = 256;
  static void SetUpTestSuite() {
    anatomy::TubeSpec spec;
    spec.radius = kRadius;
    spec.length = 0.1;
    spec.segments = kSegments;
    renderer = new AirwayRenderer(anatomy::make_tube(spec));
    camera.position = Vec3(0.0, 0.0, 0.01);
    camera.forward = Vec3::UnitZ();
    camera.up = Vec3::UnitY();
    camera.lens = Lens::kFisheye;
    camera.fov = 120.0 * kDegToRad;
  }
  static void TearDownTestSuite() { delete renderer; }
  static inline AirwayRenderer* renderer = nullptr;
  static inline Camera camera;
};

TEST_F(TubeView, SeenFromItsAxisItIsRadiallySymmetricBrightWallDarkCentre) {
  EndoscopeLook look;
  look.texture = 0.0;  // the mottling is not symmetric, by design
  const EndoscopeFrame f = renderer->render_endoscope(camera, look);
  const double focal = focal_pixels(camera);
  // Rings at 20°, 40° and 55° off-axis: brightness the same all round. The residue is the wall's 256-gon and the
  // 3 × 3 sampling on the pixel grid; 2 % of the ring's mean allows both.
  std::vector<double> ring_means;
  for (const double deg : {20.0, 40.0, 55.0}) {
    const double r = focal * deg * kDegToRad;
    std::vector<double> g;
    for (int k = 0; k < 72; ++k) {
      const double phi = 2.0 * kPi * k / 72.0;
      g.push_back(grey(f.color, 160.0 + r * std::cos(phi), 160.0 + r * std::sin(phi)));
    }
    double mean = 0.0;
    for (double v : g) mean += v / static_cast<double>(g.size());
    double worst = 0.0;
    for (double v : g) worst = std::max(worst, std::fabs(v - mean));
    EXPECT_LT(worst, 0.02 * mean) << "ring at " << deg << "°: mean " << mean << ", worst deviation " << worst;
    ring_means.push_back(mean);
  }
  const double centre = grey(f.color, 160.0, 160.0);
  std::cout << "[ tube view ] grey at the centre " << centre << ", rings at 20/40/55°: " << ring_means[0] << " / "
            << ring_means[1] << " / " << ring_means[2] << "\n";
  // Bright wall, dark centre: the far end cap (90 mm away) against the near wall.
  EXPECT_LT(centre, 0.5 * ring_means[2]);
  EXPECT_LT(ring_means[0], ring_means[1]);

  // Every pixel against the shading model evaluated on the exact cylinder (the renderer's only inputs from the
  // frame are its exposure gain): the ray at θ meets the wall at range R / sin θ with cos i = sin θ, or the cap at
  // range 90 mm / cos θ with cos i = cos θ. The 256-gon moves the wall by ≤ 7.5e-5 relative and tilts its
  // interpolated normal by < 0.01°; the 8-bit rounding and the gamma table add < 1 level. 1 grey level is the bound.
  const Mat3 frame = camera_frame(camera);
  const double half_diag2 = 0.25 * (320.0 * 320.0 + 320.0 * 320.0);
  int worst = 0, checked = 0;
  for (int y = 1; y < 320; y += 5) {
    for (int x = 2; x < 320; x += 5) {
      const Vec3 dc = camera_ray(camera, focal, x + 0.5, y + 0.5);
      const Vec3 d = frame * dc;
      if (d.z() <= 0.0) continue;
      const double rho = std::hypot(d.x(), d.y());
      const bool wall = kRadius / rho < 0.09 / d.z();
      const double t = wall ? kRadius / rho : 0.09 / d.z();
      const double cos_i = wall ? rho : d.z();
      const double dx = x + 0.5 - 160.0, dy = y + 0.5 - 160.0;
      const double weight =
          std::pow(dc.z(), look.spot_exponent) * (1.0 - look.vignetting * (dx * dx + dy * dy) / half_diag2);
      const double e = weight / (t * t + look.light_softening * look.light_softening);
      const cv::Vec3b px = f.color.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double radiance = e * (look.albedo[c] / kPi * cos_i + look.specular * std::pow(cos_i, look.shininess));
        const double expected = 255.0 * std::pow(std::min(1.0, f.gain * radiance), 1.0 / look.gamma);
        worst = std::max(worst, static_cast<int>(std::ceil(std::fabs(px[2 - c] - expected) - 0.5)));
      }
      ++checked;
    }
  }
  std::cout << "[ tube view ] " << checked << " pixels against the closed form: worst " << worst << " grey levels\n";
  EXPECT_GT(checked, 3000);
  EXPECT_LE(worst, 1);
}

TEST_F(TubeView, DepthAlongTheAxisAndAtTheWallIsTheTubesOwn) {
  const EndoscopeFrame f = renderer->render_endoscope(camera, EndoscopeLook{});
  const double focal = focal_pixels(camera);
  const Mat3 frame = camera_frame(camera);
  // Rays that reach the end cap (z = 100 mm) have z-depth 90 mm whatever their angle; a ray at θ to the axis meets
  // the wall at z-depth R / tan θ. The wall is a 256-gon inside the circle: its distance from the axis dips by up to
  // 1 − cos(π/256) = 7.5e-5 relative; Embree's single-precision hit adds ~1e-6. 2e-4 relative covers both.
  int cap = 0, wall = 0;
  double worst_cap = 0.0, worst_wall = 0.0;
  for (int y = 0; y < f.depth.rows; y += 3) {
    for (int x = 0; x < f.depth.cols; x += 3) {
      const Vec3 d = frame * camera_ray(camera, focal, x + 0.5, y + 0.5);
      const double z = f.depth.at<float>(y, x);
      const double to_cap = 0.09 / d.z();
      const double to_wall = kRadius / std::hypot(d.x(), d.y());
      if (d.z() <= 0.0) continue;
      if (to_cap < to_wall * 0.999) {
        worst_cap = std::max(worst_cap, std::fabs(z - 0.09) / 0.09);
        ++cap;
      } else if (to_wall < to_cap * 0.999) {
        const double expected = kRadius * d.z() / std::hypot(d.x(), d.y());
        worst_wall = std::max(worst_wall, std::fabs(z - expected) / expected);
        ++wall;
      }
    }
  }
  std::cout << "[ tube depth ] " << cap << " cap pixels, worst " << worst_cap << "; " << wall << " wall pixels, worst "
            << worst_wall << " (relative)\n";
  EXPECT_GT(cap, 10);
  EXPECT_GT(wall, 1000);
  EXPECT_LT(worst_cap, 2e-4);
  EXPECT_LT(worst_wall, 2e-4);
  EXPECT_NEAR(f.depth.at<float>(160, 160), 0.09, 0.09 * 2e-4);
}

TEST_F(TubeView, ToolsAreDrawnWhereTheirRaysMeetThemFirstAndShadedAsSteel) {
  // Two tools: a Ø0.91 mm needle parallel to the axis, touching a 1 mm camera below the lens (as the video draws the
  // biopsy needle), 30 mm long; and a Ø2 mm bar across the tube 30 mm ahead, from x = −8 to 8 mm, through both walls,
  // so that the wall hides its ends (as tissue hides a needle in the video). Independent of the renderer's quadratic:
  // a pixel's ray meets a tool iff its distance to the tool's segment, minimised by ternary search over the segment
  // (the distance from a point to a ray is convex along it), is at most r; where it does, the entry along the ray is
  // found by bisection on the distance to the segment (convex along the ray, positive at the lens). The nearest tool
  // takes the pixel iff its entry comes before the tube's own hit (the frame without tools). There the depth map's
  // point lies on that capsule (|dist − r| within 1e-7 m: float depth at 1–40 mm is good to ~4e-9 m) and the colour
  // is the endoscope's law with steel's reflectance and the capsule's normal at that point (1 grey level, as for the
  // wall; only unsaturated pixels test it); elsewhere the tube shows, to the bit.
  EndoscopeLook look;
  look.texture = 0.0;
  look.exposure = 2e-4;  // fixed, so that the frames with and without the tools are exposed alike
  const double r = 0.455e-3;
  const Vec3 below = -(0.5e-3 + r) * camera.up;
  const std::vector<OverviewCapsule> tools = {
      {camera.position + below, camera.position + below + Vec3(0.0, 0.0, 0.03), r},
      {Vec3(-8e-3, -2e-3, 0.04), Vec3(8e-3, -2e-3, 0.04), 1e-3}};
  const EndoscopeFrame f = renderer->render_endoscope(camera, look, 0, nullptr, tools);
  const EndoscopeFrame bare = renderer->render_endoscope(camera, look);
  const double focal = focal_pixels(camera);
  const Mat3 frame = camera_frame(camera);
  const auto to_segment = [](const OverviewCapsule& c, const Vec3& p) {
    const Vec3 ab = c.b - c.a;
    const double s = std::clamp((p - c.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (p - (c.a + s * ab)).norm();
  };
  const auto to_ray = [&](const Vec3& q, const Vec3& d) {  // distance from q to the ray lens + t d, t ≥ 0
    const Vec3 w = q - camera.position;
    return (w - std::max(0.0, w.dot(d)) * d).norm();
  };
  // The ray's entry into capsule c (+∞ if it misses it), or NaN when it grazes it (within 1e-8 m: either answer).
  const auto entry_of = [&](const OverviewCapsule& c, const Vec3& d) {
    const Vec3 ab = c.b - c.a;
    double lo = 0.0, hi = 1.0;
    for (int k = 0; k < 200; ++k) {
      const double m1 = lo + (hi - lo) / 3.0, m2 = hi - (hi - lo) / 3.0;
      if (to_ray(c.a + m1 * ab, d) < to_ray(c.a + m2 * ab, d)) {
        hi = m2;
      } else {
        lo = m1;
      }
    }
    const Vec3 q = c.a + 0.5 * (lo + hi) * ab;  // the segment's point nearest the ray
    const double gap = to_ray(q, d) - c.radius;
    if (std::fabs(gap) < 1e-8) return std::numeric_limits<double>::quiet_NaN();
    if (gap > 0.0) return std::numeric_limits<double>::infinity();
    double t0 = 0.0, t1 = std::max(0.0, (q - camera.position).dot(d));  // outside at t0, inside at t1
    for (int k = 0; k < 200; ++k) {
      const double tm = 0.5 * (t0 + t1);
      (to_segment(c, camera.position + tm * d) > c.radius ? t0 : t1) = tm;
    }
    return 0.5 * (t0 + t1);
  };
  const double half_diag2 = 0.25 * (320.0 * 320.0 + 320.0 * 320.0);
  const ToolLook steel;
  int on = 0, hidden = 0, off = 0, lit_checked = 0, worst_grey = 0;
  std::array<int, 2> per_tool{};
  double worst_surface = 0.0;
  for (int y = 0; y < 320; y += 2) {
    for (int x = 0; x < 320; x += 2) {
      const Vec3 dc = camera_ray(camera, focal, x + 0.5, y + 0.5);
      const Vec3 d = frame * dc;
      if (dc.z() <= 0.0) continue;
      const double e0 = entry_of(tools[0], d), e1 = entry_of(tools[1], d);
      if (std::isnan(e0) || std::isnan(e1)) continue;
      const std::size_t nearest = e0 <= e1 ? 0 : 1;
      const double entry = std::min(e0, e1);
      const double z = f.depth.at<float>(y, x);
      const double z_bare = bare.depth.at<float>(y, x);
      if (!(entry * dc.z() < z_bare)) {  // the tube's hit comes first, or the ray misses both tools
        ++(std::isinf(entry) ? off : hidden);
        EXPECT_EQ(z, z_bare) << "pixel " << x << ", " << y << " should see the tube";
        continue;
      }
      ++on;
      ++per_tool[nearest];
      const OverviewCapsule& c = tools[nearest];
      const Vec3 p = camera.position + (z / dc.z()) * d;
      worst_surface = std::max(worst_surface, std::fabs(to_segment(c, p) - c.radius));
      const Vec3 ab = c.b - c.a;
      const double s = std::clamp((p - c.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      const Vec3 n = (p - (c.a + s * ab)).normalized();
      const double t = (p - camera.position).norm();
      const double cos_i = std::fabs(n.dot(d));
      const double dx = x + 0.5 - 160.0, dy = y + 0.5 - 160.0;
      const double weight =
          std::pow(dc.z(), look.spot_exponent) * (1.0 - look.vignetting * (dx * dx + dy * dy) / half_diag2);
      const double e = weight / (t * t + look.light_softening * look.light_softening);
      const cv::Vec3b px = f.color.at<cv::Vec3b>(y, x);
      if (px[0] == 255 || px[1] == 255 || px[2] == 255) continue;  // saturated: the law is clipped there
      ++lit_checked;
      for (int ch = 0; ch < 3; ++ch) {
        const double radiance =
            e * (steel.albedo[ch] / kPi * cos_i + steel.specular * std::pow(cos_i, steel.shininess));
        const double expected = 255.0 * std::pow(std::min(1.0, f.gain * radiance), 1.0 / look.gamma);
        worst_grey = std::max(worst_grey, static_cast<int>(std::ceil(std::fabs(px[2 - ch] - expected) - 0.5)));
      }
    }
  }
  std::cout << "[ tube view ] tools: " << on << " pixels on them (needle " << per_tool[0] << ", bar " << per_tool[1]
            << "; " << lit_checked << " unsaturated), " << hidden << " hidden by the wall, " << off
            << " off; worst depth off the surface " << worst_surface << " m, worst colour " << worst_grey
            << " grey levels\n";
  EXPECT_GT(per_tool[0], 500);  // a needle touching the lens fills a wedge of the lower image
  EXPECT_GT(per_tool[1], 50);   // the bar's middle: ±4.6 mm at 30 mm, 2 mm thick, about 23 × 5 sampled pixels
  EXPECT_GT(hidden, 50);        // its ends behind the wall, about as many
  EXPECT_GT(lit_checked, 200);
  EXPECT_GT(off, 5000);
  EXPECT_LT(worst_surface, 1e-7);
  EXPECT_LE(worst_grey, 1);
  // A lens inside a tool is refused.
  const OverviewCapsule through{camera.position - Vec3(0, 0, 1e-3), camera.position + Vec3(0, 0, 0.02), r};
  EXPECT_THROW(renderer->render_endoscope(camera, look, 0, nullptr, std::span(&through, 1)), InputError);
  // ray_capsule from inside answers nothing, also where a ball's entry lies ahead.
  EXPECT_FALSE(ray_capsule(through.a + Vec3(0, 0, 2e-3), Vec3::UnitZ(), through));
}

TEST_F(TubeView, SameSeedSamePixelsAndThreadsDoNotChangeThem) {
  EndoscopeLook look;
  look.noise = 3.0;
  look.seed = 7;
  const cv::Mat a = renderer->render_endoscope(camera, look, 5).color;
  const cv::Mat b = renderer->render_endoscope(camera, look, 5).color;
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  anatomy::TubeSpec spec;
  spec.radius = kRadius;
  spec.length = 0.1;
  spec.segments = kSegments;
  const AirwayRenderer two(anatomy::make_tube(spec), 2);
  EXPECT_EQ(cv::norm(a, two.render_endoscope(camera, look, 5).color, cv::NORM_INF), 0.0);
  look.seed = 8;
  const cv::Mat c = renderer->render_endoscope(camera, look, 5).color;
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, renderer->render_endoscope(camera, look, 6).color, cv::NORM_L1), 0.0);
}

TEST_F(TubeView, AutoExposureEasesFromFrameToFrame) {
  AutoExposure ae;
  EndoscopeLook look;
  const EndoscopeFrame first = renderer->render_endoscope(camera, look, 0, &ae);
  EXPECT_EQ(ae.gain, first.gain);
  Camera closer = camera;
  closer.position.x() = 3e-3;  // near the wall: brighter, so the ideal gain drops
  const double ideal = renderer->render_endoscope(closer, look).gain;
  const EndoscopeFrame next = renderer->render_endoscope(closer, look, 1, &ae);
  EXPECT_LT(ideal, first.gain);
  EXPECT_NEAR(std::log(next.gain), 0.5 * (std::log(first.gain) + std::log(ideal)), 1e-9);
}

TEST(Endoscope, ABronchialPhantomFrameIsNeitherBlackNorSaturated) {
  anatomy::BronchialTreeParams p;
  p.max_generation = 3;
  const anatomy::Phantom tree = anatomy::make_bronchial_tree(p);
  const AirwayRenderer renderer(tree.mesh);
  // Down the trachea from a quarter of its length, towards the carina.
  const auto& trachea = tree.graph.branches.front();
  const Vec3 a = tree.graph.nodes[trachea.nodes.front()].position;
  const Vec3 b = tree.graph.nodes[trachea.nodes.back()].position;
  Camera cam;
  cam.position = a + 0.25 * (b - a);
  cam.forward = b - a;
  cam.up = (b - a).unitOrthogonal();
  const EndoscopeFrame f = renderer.render_endoscope(cam, EndoscopeLook{});
  cv::Mat g;
  cv::cvtColor(f.color, g, cv::COLOR_BGR2GRAY);
  const double mean = cv::mean(g)[0];
  const double saturated = cv::countNonZero(g >= 254) / static_cast<double>(g.total());
  const double black = cv::countNonZero(g <= 5) / static_cast<double>(g.total());
  std::cout << "[ phantom frame ] mean grey " << mean << ", saturated " << 100 * saturated << " %, black "
            << 100 * black << " %\n";
  EXPECT_GT(mean, 30.0);
  EXPECT_LT(mean, 200.0);
  EXPECT_LT(saturated, 0.05);  // auto-exposure puts the 95th percentile below white
  EXPECT_LT(black, 0.25);      // the carina, 10 cm of airway deep, still gets light
}

/// The angle between two directions [deg].
double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) / kDegToRad;
}

TEST(Lumen, ATubeSeenFromOffItsAxisShowsOneLumenWhereTheTubeGoes) {
  // A Ø12 mm, 120 mm tube, the camera 2 mm off its axis, 20 mm in, turned 20° off it: the one dark opening is the
  // far end, whose ray runs along the axis (its vanishing point). Tolerance 4°: the end cap is 100 mm away and 6 mm
  // in radius (3.4° seen from the lens), and the blob's darkness-weighted centre may sit anywhere on it (measured:
  // 2.7°).
  const anatomy::Phantom tube = anatomy::make_tube_phantom(anatomy::TubeParams{});
  const AirwayRenderer renderer(tube.mesh);
  Camera cam;
  cam.position = Vec3(20e-3, 2e-3, 0.0);
  cam.forward = Vec3(std::cos(20 * kDegToRad), 0.0, std::sin(20 * kDegToRad));
  cam.up = Vec3::UnitZ();
  cam.fov = 120 * kDegToRad;
  const EndoscopeFrame f = renderer.render_endoscope(cam, EndoscopeLook{});
  const std::vector<Lumen> lumens = detect_lumens(f.color, cam);
  ASSERT_EQ(lumens.size(), 1u);
  const Vec3 seen = camera_frame(cam) * lumens.front().direction;
  std::cout << "[ tube ] lumen " << angle_deg(seen, Vec3::UnitX()) << " deg off the axis, area "
            << 100 * lumens.front().area << " %\n";
  EXPECT_LT(angle_deg(seen, Vec3::UnitX()), 4.0);
}

TEST(Lumen, AboveTheCarinaBothMainBronchiShowEachWhereItGoes) {
  // The generated tree (Weibel A, generation 2), the camera on the trachea's axis 25 mm above its end, looking down
  // it: two openings, each nearest in direction to its own main bronchus (the ray to the point 20 mm into it).
  // Tolerance 12°: the opening of a bronchus seen from above is its near part (the far part hides behind the
  // carina's spur), which lies off the ray to its centreline by up to the bronchus's angular radius (6 mm at ~45 mm,
  // 8°) plus the curve of the blend.
  anatomy::BronchialTreeParams p;
  p.max_generation = 2;
  const anatomy::Phantom tree = anatomy::make_bronchial_tree(p);
  const AirwayRenderer renderer(tree.mesh);
  const anatomy::AirwayGraph& g = tree.graph;
  const auto& trachea = g.branches.front();
  const Vec3 a = g.nodes[trachea.nodes.front()].position;
  const Vec3 b = g.nodes[trachea.nodes.back()].position;
  Camera cam;
  cam.position = b - 25e-3 * (b - a).normalized();
  cam.forward = b - a;
  cam.up = (b - a).unitOrthogonal();
  cam.fov = 120 * kDegToRad;
  const EndoscopeFrame f = renderer.render_endoscope(cam, EndoscopeLook{});
  const std::vector<Lumen> lumens = detect_lumens(f.color, cam);
  ASSERT_EQ(lumens.size(), 2u);
  std::vector<Vec3> bronchi;
  for (const int c : trachea.children) {
    const auto& br = g.branches[static_cast<std::size_t>(c)];
    Vec3 x = g.nodes[br.nodes.front()].position;
    double run = 0.0;
    for (std::size_t k = 1; k < br.nodes.size() && run < 20e-3; ++k) {
      const Vec3 y = g.nodes[br.nodes[k]].position;
      run += (y - x).norm();
      x = y;
    }
    bronchi.push_back(x - cam.position);
  }
  for (const Lumen& l : lumens) {
    const Vec3 seen = camera_frame(cam) * l.direction;
    const double d0 = angle_deg(seen, bronchi[0]);
    const double d1 = angle_deg(seen, bronchi[1]);
    std::cout << "[ carina ] lumen at " << d0 << " / " << d1 << " deg from the main bronchi, area " << 100 * l.area
              << " %\n";
    EXPECT_LT(std::min(d0, d1), 12.0);
    EXPECT_GT(std::max(d0, d1), 2.0 * std::min(d0, d1));
  }
  const double first = angle_deg(camera_frame(cam) * lumens[0].direction, bronchi[0]);
  const double second = angle_deg(camera_frame(cam) * lumens[1].direction, bronchi[0]);
  EXPECT_NE(first < 12.0, second < 12.0);  // one opening per bronchus
}

TEST(Lumen, BadFramesAndSettingsAreRefused) {
  Camera cam;
  EXPECT_THROW(detect_lumens(cv::Mat(), cam), InputError);
  EXPECT_THROW(detect_lumens(cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)), cam), InputError);
  LumenSettings s;
  s.levels = {1.5};
  EXPECT_THROW(detect_lumens(cv::Mat(8, 8, CV_8UC3, cv::Scalar(0, 0, 0)), cam, s), InputError);
  s.levels = {0.3, 0.1};  // the lowest level wins ties: they must ascend
  EXPECT_THROW(detect_lumens(cv::Mat(8, 8, CV_8UC3, cv::Scalar(0, 0, 0)), cam, s), InputError);
  // A black frame has no lumen to tell from the wall.
  EXPECT_TRUE(detect_lumens(cv::Mat(8, 8, CV_8UC3, cv::Scalar(0, 0, 0)), cam).empty());
}

TEST(Endoscope, AMovedAirwaySeesWhatOneBuiltOnTheMovedMeshSees) {
  // AirwayRenderer::move (a breathing airway in the videos): a tube bent and stretched by a smooth map, refitted,
  // against a renderer built on the bent mesh, from a camera inside the bent tube. Depth within 1e-5 relative (Embree
  // refits a tree whose boxes differ from a fresh build's, the hits are the same triangles' float intersections);
  // colour within half a grey level on average (the same normals, auto-exposure from the same frame).
  const anatomy::Phantom tube = anatomy::make_tube_phantom(anatomy::TubeParams{});
  anatomy::TriangleMesh bent = tube.mesh;
  std::vector<Vec3> halfway = tube.mesh.vertices;
  for (std::size_t i = 0; i < bent.vertices.size(); ++i) {
    Vec3& v = bent.vertices[i];
    const Vec3 u(0.0, 0.08 * v.x() * v.x() / 0.12, 0.004 * std::sin(v.x() / 0.03));
    v += u;
    halfway[i] += 0.5 * u;
  }
  // Moved twice: the first move builds the tree Embree refits, the second refits it (the path every later frame of a
  // breathing airway takes).
  AirwayRenderer moved(tube.mesh);
  moved.move(halfway);
  moved.move(bent.vertices);
  const AirwayRenderer fresh(bent);
  Camera cam;
  const double x = 0.03;
  cam.position = Vec3(x, 0.08 * x * x / 0.12, 0.004 * std::sin(x / 0.03));
  cam.forward = Vec3(1.0, 2.0 * 0.08 * x / 0.12, 0.004 / 0.03 * std::cos(x / 0.03));
  cam.up = Vec3::UnitZ();
  cam.fov = 120 * kDegToRad;
  const EndoscopeFrame a = moved.render_endoscope(cam, EndoscopeLook{});
  const EndoscopeFrame b = fresh.render_endoscope(cam, EndoscopeLook{});
  double worst = 0.0;
  for (int y = 0; y < a.depth.rows; ++y) {
    for (int i = 0; i < a.depth.cols; ++i) {
      const float da = a.depth.at<float>(y, i);
      const float db = b.depth.at<float>(y, i);
      worst = std::max(worst, std::abs(static_cast<double>(da) - db) / std::max(1e-9, static_cast<double>(db)));
    }
  }
  cv::Mat diff;
  cv::absdiff(a.color, b.color, diff);
  const double mean = cv::mean(diff)[0];
  std::cout << "[ moved airway ] depth within " << worst << " relative, colour " << mean << " grey levels apart\n";
  EXPECT_LT(worst, 1e-5);
  EXPECT_LT(mean, 0.5);
  EXPECT_THROW(moved.move(std::vector<Vec3>(3, Vec3::Zero())), InputError);
}

TEST(Files, AVideoReadsBackWithItsFrameCountAndSize) {
  const fs::path dir = scratch("video");
  VideoFile v(dir / "clip", 30.0, 96, 64);
  EXPECT_FALSE(fs::exists(v.path()));  // nothing under the final name while writing
  for (int k = 0; k < 12; ++k) v.write(cv::Mat(64, 96, CV_8UC3, cv::Scalar(10 * k, 100, 200 - 10 * k)));
  const fs::path out = v.finish();
  ASSERT_TRUE(fs::exists(out));
  std::cout << "[ video ] " << out.filename() << " codec " << v.codec() << "\n";
  cv::VideoCapture in(out.string());
  ASSERT_TRUE(in.isOpened());
  int frames = 0;
  cv::Mat m;
  while (in.read(m)) {
    EXPECT_EQ(m.cols, 96);
    EXPECT_EQ(m.rows, 64);
    ++frames;
  }
  EXPECT_EQ(frames, 12);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}), 1);  // no partial file left
  EXPECT_THROW(v.write(m), InputError);
}

TEST(Files, WithoutAnMp4WriterTheVideoIsAnMjpgAvi) {
  const fs::path dir = scratch("avi");
  VideoFile v(dir / "clip", 25.0, 64, 48, VideoFile::Container::kAvi);
  EXPECT_EQ(v.codec(), "MJPG");
  for (int k = 0; k < 7; ++k) v.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(30 * k, 60, 90)));
  const fs::path out = v.finish();
  EXPECT_EQ(out.filename(), "clip.avi");
  cv::VideoCapture in(out.string());
  ASSERT_TRUE(in.isOpened());
  int frames = 0;
  cv::Mat m;
  while (in.read(m)) {
    EXPECT_EQ(m.size(), cv::Size(64, 48));
    ++frames;
  }
  EXPECT_EQ(frames, 7);
}

TEST(Files, AnAbandonedVideoLeavesNothing) {
  const fs::path dir = scratch("abandoned");
  {
    VideoFile v(dir / "clip", 30.0, 32, 32);
    v.write(cv::Mat(32, 32, CV_8UC3, cv::Scalar(1, 2, 3)));
    EXPECT_THROW(v.write(cv::Mat(16, 32, CV_8UC3)), InputError);
  }
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(Files, DepthPngHoldsMillimetresOnTheC3vdScale) {
  const fs::path dir = scratch("depth");
  cv::Mat d(2, 2, CV_32F);
  d.at<float>(0, 0) = 0.0f;   // no hit
  d.at<float>(0, 1) = 0.05f;  // 50 mm: half the 100 mm range
  d.at<float>(1, 0) = 0.2f;   // beyond the range: clamped
  d.at<float>(1, 1) = 1e-9f;  // a hit at the lens still reads as a hit
  write_png(dir / "d.png", depth_to_u16(d, 0.1));
  const cv::Mat back = cv::imread((dir / "d.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_16U);
  EXPECT_EQ(back.at<std::uint16_t>(0, 0), 0);
  EXPECT_EQ(back.at<std::uint16_t>(0, 1), 32768);  // round(0.5 · 65535)
  EXPECT_EQ(back.at<std::uint16_t>(1, 0), 65535);
  EXPECT_EQ(back.at<std::uint16_t>(1, 1), 1);
}

TEST(Overview, ShowsTheBodyInsideTheSemiTransparentAirwayAndTheMagnetsPoles) {
  anatomy::TubeSpec spec;
  spec.radius = 6e-3;
  spec.length = 0.1;
  const AirwayRenderer renderer(anatomy::make_tube(spec));
  OverviewContent content;
  for (int i = 0; i <= 10; ++i) content.body.push_back(Vec3(0.0, 0.0, 0.005 + 0.006 * i));
  content.body_radius = 2.5e-3;
  content.magnets.push_back({Vec3(0.06, 0.0, 0.05), Vec3::UnitZ(), 0.03, 0.03});
  content.target = Vec3(0.0, 0.0, 0.09);
  Camera cam;
  cam.lens = Lens::kPinhole;
  cam.fov = 60.0 * kDegToRad;
  cam.width = 320;
  cam.height = 240;
  cam.position = Vec3(0.03, -0.25, 0.05);
  cam.forward = Vec3(0.0, 1.0, 0.0);
  cam.up = Vec3::UnitZ();
  const cv::Mat img = renderer.render_overview(cam, content);
  const auto pixel = [&](const Vec3& p) {
    const auto q = project_direction(cam, p - cam.position);
    return img.at<cv::Vec3b>(static_cast<int>(q->y()), static_cast<int>(q->x()));
  };
  const cv::Vec3b body = pixel(Vec3(0.0, 0.0, 0.03));     // BGR: blue above red (seen through the wall)
  const cv::Vec3b north = pixel(Vec3(0.06, 0.0, 0.058));  // red
  const cv::Vec3b south = pixel(Vec3(0.06, 0.0, 0.042));  // blue
  const cv::Vec3b target = pixel(Vec3(0.0, 0.0, 0.09));   // green
  const cv::Vec3b wall = pixel(Vec3(0.0045, 0.0, 0.07));  // pink: beside the body, through both walls
  EXPECT_GT(body[0], body[2]);
  EXPECT_GT(north[2], north[0] + 60);
  EXPECT_GT(south[0], south[2] + 60);
  EXPECT_GT(target[1], target[2]);
  EXPECT_GT(wall[2], wall[0]);
}

}  // namespace
}  // namespace magvine::render
