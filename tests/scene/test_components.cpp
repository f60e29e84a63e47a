// Components are built only when a scene uses them (issue 6, DESIGN.md): core/usage.hpp counts what a run built.
// A free-space scene builds no collision world; a uniform field builds no gradient evaluation; an experiment builds
// one collision world and no FCL distance model (no distance metric asks for one); magnets with gradients build
// a gradient field only when the scene has them, and no renderer without outputs.video.

#include <gtest/gtest.h>

#include <filesystem>

#include "magvine/core/usage.hpp"
#include "magvine/scene/experiment.hpp"
#include "magvine/scene/free_space.hpp"
#include "magvine/scene/navigator.hpp"
#include "magvine/scene/trials.hpp"

namespace magvine::scene {
namespace {

using usage::Component;

const std::filesystem::path kScenes = std::filesystem::path(MAGVINE_SOURCE_DIR) / "assets/scenes";

TEST(Components, AFreeSpaceRodInAUniformFieldBuildsNoWorldNoGradient) {
  usage::reset();
  const FreeSpaceResult r = solve_free_space(load_free_space_scene(kScenes / "rod_uniform_field.yaml"));
  ASSERT_TRUE(r.report.converged);
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 0u);
  EXPECT_EQ(usage::count(Component::kGradientField), 0u);
}

TEST(Components, AFreeSpaceVineUnderTheEpmBuildsItsGradientButNoWorld) {
  usage::reset();
  const FreeSpaceResult r = solve_free_space(load_free_space_scene(kScenes / "skin_vine_epm.yaml"));
  ASSERT_TRUE(r.report.converged);
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 0u);
  EXPECT_EQ(usage::count(Component::kGradientField), 1u);
}

TEST(Components, AnExperimentBuildsOneWorldAndAGradientOnlyWithMagnets) {
  // The collision world is built once, with the scene's anatomy when it loads; runs and trials share it.
  usage::reset();
  ExperimentScene scene = load_experiment_scene(kScenes / "y_bifurcation_fluid_vine.yaml");
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 1u);
  scene.duration = 0.2;
  usage::reset();
  (void)run_experiment(scene);
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 0u);
  EXPECT_GE(usage::count(Component::kGradientField), 1u);  // one per magnet pose (it moves every step)
  EXPECT_EQ(usage::count(Component::kRenderer), 0u);       // no outputs.video (test_video_outputs: one with it)
  scene.magnets.reset();
  scene.magnet_keyframes.clear();
  usage::reset();
  (void)run_experiment(scene);
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 0u);
  EXPECT_EQ(usage::count(Component::kGradientField), 0u);
  // Four trials on two threads: no world of their own.
  usage::reset();
  (void)run_trials(scene, {}, 4, 2);
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 0u);
}

TEST(Components, ScenesLoadedThroughOneCacheShareOneAnatomy) {
  usage::reset();
  AnatomyCache cache;
  const ExperimentScene a = load_experiment_scene(kScenes / "y_bifurcation_fluid_vine.yaml", &cache);
  const ExperimentScene b = load_experiment_scene(kScenes / "y_bifurcation_magnetic_rod.yaml", &cache);
  EXPECT_EQ(a.anatomy.get(), b.anatomy.get());
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 1u);
  const ExperimentScene c = load_experiment_scene(kScenes / "constriction_skin_vine.yaml", &cache);
  EXPECT_NE(a.anatomy.get(), c.anatomy.get());
  EXPECT_EQ(usage::count(Component::kCollisionWorld), 2u);
}

}  // namespace
}  // namespace magvine::scene
