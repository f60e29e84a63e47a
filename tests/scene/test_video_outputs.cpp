// outputs.video (issue 7): a run films its tip camera and an overview into videos that read back with the frame
// count its duration, speed and frame rate give; depth and PNG frames on request; bad video keys are refused with
// the file and key; the renderer is built only for a scene that asks for a video. Built with the render module only.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "magvine/core/error.hpp"
#include "magvine/core/usage.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/trials.hpp"

namespace magvine::scene {
namespace {

namespace fs = std::filesystem;
const fs::path kDemo = fs::path(MAGVINE_SOURCE_DIR) / "assets/scenes/y_bifurcation_fluid_vine.yaml";

std::string demo_text() {
  std::ifstream in(kDemo);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// The demo scene, 0.5 s long, with `outputs` appended.
std::string with_outputs(const std::string& outputs) {
  std::string text = demo_text();
  const auto at = text.find("duration: 8");
  text.replace(at, 11, "duration: 0.5");
  return text + outputs;
}

int frames_in(const fs::path& file) {
  cv::VideoCapture in(file.string());
  int n = 0;
  cv::Mat m;
  while (in.read(m)) ++n;
  return n;
}

TEST(VideoOutputs, ARunFilmsItsTipAndAnOverviewWithTheFramesItsDurationGives) {
  const ExperimentScene scene = parse_experiment_scene(
      with_outputs("outputs:\n  video:\n"
                   "    - {camera: tip, size: [96, 96], fps: 20, depth: true, frames: true}\n"
                   "    - {camera: overview, size: [128, 96], fps: 10, speed: 0.5}\n"),
      kDemo.string(), kDemo.parent_path());
  usage::reset();
  const ExperimentResult r = run_experiment(scene);
  EXPECT_EQ(usage::count(usage::Component::kRenderer), 0u);  // the run itself renders nothing
  const fs::path dir = fs::temp_directory_path() / "magvine_test_video_outputs";
  fs::remove_all(dir);
  write_experiment_outputs(scene, r, dir);
  EXPECT_EQ(usage::count(usage::Component::kRenderer), 1u);  // one renderer serves both cameras
  // 0.5 s at 20 frames/s: frames at 0, 0.05, …, 0.5 s → 11. The overview at half speed and 10 frames/s: a frame
  // every 0.05 simulated seconds → 11 too.
  const double simulated = r.samples.back().time;
  const int tip_frames = static_cast<int>(std::floor(simulated * 20.0 + 1e-6)) + 1;
  EXPECT_EQ(frames_in(dir / "tip.mp4"), tip_frames);
  EXPECT_EQ(frames_in(dir / "overview.mp4"), static_cast<int>(std::floor(simulated / 0.05 + 1e-6)) + 1);
  cv::VideoCapture overview((dir / "overview.mp4").string());
  EXPECT_EQ(overview.get(cv::CAP_PROP_FRAME_WIDTH), 128);
  EXPECT_EQ(overview.get(cv::CAP_PROP_FRAME_HEIGHT), 96);
  // PNG frames and 16-bit depth maps, one per video frame, and the depth scale.
  int pngs = 0, depths = 0;
  for (const auto& e : fs::directory_iterator(dir / "tip_frames")) pngs += e.path().extension() == ".png";
  for (const auto& e : fs::directory_iterator(dir / "tip_depth")) depths += e.path().extension() == ".png";
  EXPECT_EQ(pngs, tip_frames);
  EXPECT_EQ(depths, tip_frames);
  const cv::Mat d = cv::imread((dir / "tip_depth/000000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(d.type(), CV_16U);
  // Inside the closed phantom every ray meets the wall. The tip starts 7 mm along the parent (its bifurcation at
  // 60 mm, daughters 50 mm long at ±35°), looking down it: the farthest z-depth lies beyond the carina's ridge
  // (53 mm ahead) and short of the daughters' blind ends (53 + 50 cos 35° = 94 mm ahead).
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(d, &lo, &hi);
  EXPECT_GT(lo, 0.0);
  EXPECT_GT(hi * 0.1 / 65535.0, 0.053);
  EXPECT_LT(hi * 0.1 / 65535.0, 0.094);
  std::ifstream scale_file(dir / "tip_depth/depth.json");
  const auto scale = nlohmann::json::parse(scale_file);
  EXPECT_DOUBLE_EQ(scale["range_m"].get<double>(), 0.1);
  std::ifstream metrics_file(dir / "metrics.json");
  const auto metrics = nlohmann::json::parse(metrics_file);
  ASSERT_EQ(metrics["videos"].size(), 2u);
  EXPECT_EQ(metrics["videos"][0]["file"], "tip.mp4");
  EXPECT_EQ(metrics["videos"][0]["frames"], tip_frames);
  EXPECT_EQ(metrics["videos"][1]["camera"], "overview");
  // Nothing partial left behind.
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
  }
}

TEST(VideoOutputs, SameSceneSamePixels) {
  const ExperimentScene scene = parse_experiment_scene(
      with_outputs("outputs: {video: {camera: tip, size: [64, 64], fps: 10, noise: 2, frames: true}}\n"),
      kDemo.string(), kDemo.parent_path());
  const fs::path a = fs::temp_directory_path() / "magvine_test_video_a";
  const fs::path b = fs::temp_directory_path() / "magvine_test_video_b";
  write_experiment_outputs(scene, run_experiment(scene), a);
  write_experiment_outputs(scene, run_experiment(scene), b);
  for (const char* f : {"tip_frames/000000.png", "tip_frames/000003.png"}) {
    const cv::Mat x = cv::imread((a / f).string());
    const cv::Mat y = cv::imread((b / f).string());
    ASSERT_FALSE(x.empty());
    EXPECT_EQ(cv::norm(x, y, cv::NORM_INF), 0.0) << f;
  }
}

TEST(VideoOutputs, BadVideoKeysNameTheFileAndKey) {
  const auto error_of = [](const std::string& outputs) -> std::string {
    try {
      (void)parse_experiment_scene(with_outputs(outputs), "bad.yaml", kDemo.parent_path());
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  const auto expect = [&](const std::string& outputs, const std::string& part) {
    const std::string what = error_of(outputs);
    EXPECT_NE(what.find("bad.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find(part), std::string::npos) << what;
  };
  expect("outputs: {video: {camera: nose}}\n", "outputs.video.camera: must be tip or overview");
  expect("outputs: {video: {camera: tip, sise: [64, 64]}}\n", "did you mean 'size'");
  expect("outputs: {video: {camera: tip, size: [63, 64]}}\n", "outputs.video.size: video codecs need even sides");
  expect("outputs: {video: {camera: tip, lens: pinhole, fov: 180}}\n", "outputs.video.fov");
  expect("outputs: {video: {camera: overview, depth: true}}\n", "outputs.video.depth");
  expect("outputs: {video: [{camera: tip}, {camera: tip, fps: 10}]}\n", "two tip videos");
  expect("outputs: {video: [{camera: tip}, {camera: tip, from: [1, 0, 0]}]}\n", "outputs.video[1].from");
  expect("outputs: {video: {camera: overview, from: [0, 0, 1], up: [0, 0, 2]}}\n", "outputs.video.up");
}

}  // namespace
}  // namespace magvine::scene
