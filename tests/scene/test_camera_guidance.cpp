// Camera-guided navigation (issue 31 item 3; control.navigator.guidance: camera): the navigator steers from the
// lumens its tip camera shows and the plan, never from the tip's position, and reaches a generation-3 branch of the
// generated tree; its dead reckoning along the plan against the true tip; the guidance keys refused where they do
// not belong. Built with the render module only (the tip camera is the video plugin's).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/navigator.hpp"
#include "support/text_file.hpp"

namespace magvine::scene {
namespace {

namespace fs = std::filesystem;
const fs::path kScene = fs::path(MAGVINE_SOURCE_DIR) / "assets/scenes/bronchial_tree_camera_navigator.yaml";

std::string scene_text() {
  return test::text_of(kScene);
}

/// The bundled scene's text with `from` replaced by `to` (which must occur).
std::string edited(const std::string& from, const std::string& to) {
  std::string text = scene_text();
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(CameraGuidance, TheCameraNavigatorReachesAGenerationThreeBranch) {
  const ExperimentScene scene =
      parse_experiment_scene(edited("frames: true", "frames: false"), kScene.string(), kScene.parent_path());
  ASSERT_TRUE(scene.navigator && scene.navigator->camera);
  const ExperimentResult r = run_experiment(scene);
  ASSERT_TRUE(r.converged) << r.failure;
  EXPECT_TRUE(r.success);
  ASSERT_FALSE(r.samples.empty());
  EXPECT_EQ(scene.anatomy->graph->branches[static_cast<std::size_t>(r.samples.back().branch)].name, "0-0-0-0");
  // Dead reckoning (the base's arc along the plan plus the everted length) against the tip's true arc: within 7.6 mm,
  // the length of a generation-3 branch (Weibel A), so that the junction it decides about is the one ahead.
  ASSERT_FALSE(r.guidance.empty());
  double drift = 0.0;
  int choices = 0;
  for (const GuidanceSample& g : r.guidance) {
    drift = std::max(drift, std::abs(g.arc - g.true_arc));
    choices += g.lumens > 1 && g.junction >= 0;
  }
  std::cout << "[ camera guidance ] reached at " << r.time_to_target << " s, " << r.guidance.size() << " placements, "
            << choices << " choices between lumens at a junction, dead reckoning off by at most " << 1e3 * drift
            << " mm\n";
  EXPECT_LT(drift, 7.6e-3);
  // It saw the junctions: choices between two or more openings before each of the plan's three junctions.
  for (int j = 0; j < 3; ++j) {
    EXPECT_TRUE(std::any_of(r.guidance.begin(), r.guidance.end(),
                            [j](const GuidanceSample& g) { return g.junction == j && g.lumens > 1; }))
        << "junction " << j;
  }
}

TEST(CameraGuidance, APlacementDoesNotReadTheTipsPosition) {
  // Two navigators shown the same lumens, told different tips (one not even a number), place the magnet alike: the
  // camera-guided placement reads the orientation and the everted length only.
  const ExperimentScene scene = parse_experiment_scene(scene_text(), kScene.string(), kScene.parent_path());
  const auto lumens = []() {
    return std::vector<SeenLumen>{{Vec3(0.3, 0.1, -1.0).normalized(), 0.01},
                                  {Vec3(-0.3, 0.0, -1.0).normalized(), 0.02}};
  };
  NavigatorController a(scene);
  NavigatorController b(scene);
  a.use_camera(lumens);
  b.use_camera(lumens);
  std::vector<RunEvent> events;
  const Mat3 frame = scene.base_frame;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const double length : {0.03, 0.09}) {
    const double t = 10.0 * length;  // 0.3 and 0.9 s: a placement each (every 0.1 s)
    a.place(t, Vec3(nan, nan, nan), frame, length, events);
    b.place(t, Vec3(0.05, -0.02, 0.3), frame, length, events);
    EXPECT_TRUE(a.pose().position.allFinite());
    EXPECT_EQ(a.pose().position, b.pose().position);
    EXPECT_EQ(a.pose().axis, b.pose().axis);
  }
  ASSERT_EQ(a.guidance().size(), 2u);
  EXPECT_EQ(a.guidance().back().lumens, 2);

  // Blind (no lumen) and past the plan's end by dead reckoning: the magnet pulls along the plan's last segment.
  NavigatorController blind(scene);
  blind.use_camera([] { return std::vector<SeenLumen>{}; });
  blind.place(0.5, Vec3::Zero(), frame, 0.5, events);
  const std::vector<Vec3>& path = blind.path();
  const Vec3 last = (path.back() - path[path.size() - 2]).normalized();
  ASSERT_EQ(blind.guidance().size(), 1u);
  EXPECT_EQ(blind.guidance().back().chosen, -1);
  EXPECT_NEAR((blind.guidance().back().line - last).norm(), 0.0, 1e-12);
  EXPECT_TRUE(blind.pose().position.allFinite());
}

TEST(CameraGuidance, GuidanceKeysAreRefusedWhereTheyDoNotBelong) {
  const auto fails = [](const std::string& text, const std::string& needle) {
    try {
      (void)parse_experiment_scene(text, kScene.string(), kScene.parent_path());
      ADD_FAILURE() << "accepted: " << needle;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  const std::string guidance = "guidance: {mode: camera, size: 160, fov: 120, frames: true}";
  fails(edited(guidance, "guidance: {mode: sonar}"), "must be oracle or camera");
  fails(edited(guidance, "guidance: {mode: oracle, size: 160}"), "size");
  fails(edited(guidance, "guidance: {mode: camera, fov: 200}"), "fov");
  fails(edited("max_generation: 4}\n", "max_generation: 4}\n  breathing: {period: 4}\n"), "not with anatomy.breathing");
}

}  // namespace
}  // namespace magvine::scene
