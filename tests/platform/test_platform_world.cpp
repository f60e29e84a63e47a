// The platform's Bullet world (platform/platform.hpp): Bullet's articulated body against the arm model (frames and
// holding torques, two independent computations), the clearance of the magnet from the torso against the ellipse by
// hand, and collisions with the table.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "magvine/core/units.hpp"
#include "magvine/platform/platform.hpp"

namespace magvine::platform {
namespace {

ArmMount epm_mount(const Iso3& base) {
  ArmMount m;
  m.base = base;
  m.tool.flange_to_magnet.translation() = Vec3(0, 0, 0.05 + 0.0508);
  m.tool.mass = 6.18;
  m.tool.com = Vec3(0, 0, 0.05 + 0.0508);
  return m;
}

// An adult torso (0.33 × 0.25 m) lying supine round a carina at the origin (trachea along −z, front −y), its top
// 0.09 m above it, on the table; no arms yet.
PlatformModel supine_patient() {
  PlatformModel model;
  model.body = TorsoModel{};
  model.table = TableModel{};
  place_patient(Vec3::Zero(), Vec3(0, 0, -1), Vec3(0, -1, 0), 0.09, *model.body, &*model.table);
  return model;
}

TEST(PlatformWorld, BulletFramesAndTorquesMatchTheArmModel) {
  PlatformModel model;
  Iso3 base = Iso3::Identity();
  base.linear() = Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  base.translation() = Vec3(0.2, -0.1, 0.05);
  model.arms.push_back(epm_mount(base));
  model.gravity = Vec3(0.5, -1.0, -9.7);
  PlatformWorld world(model);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int n = 0; n < 20; ++n) {
    JointVector q;
    for (int i = 0; i < kArmJoints; ++i) q[i] = unit(rng) * model.arm.q_max[i];
    world.set_joints(0, q);
    const std::array<Iso3, kArmJoints> mine = link_frames(model.arm, base, q);
    const std::array<Iso3, kArmJoints> bullet = world.bullet_link_frames(0);
    for (int i = 0; i < kArmJoints; ++i) {
      EXPECT_LT((mine[i].matrix() - bullet[i].matrix()).norm(), 1e-12) << "link " << i + 1;
    }
    // Holding torques by Bullet's articulated-body algorithm and by the Jacobian transpose, with a wrench on the
    // magnet.
    const Vec3 f(3.0, -20.0, 7.0), t(0.5, 0.2, -1.0);
    const Vec3 centre = magnet_pose(model.arm, model.arms[0], q).translation();
    const JointVector expected = holding_torques(model.arm, model.arms[0].tool, base, q, model.gravity, f, t, centre);
    const JointVector got = world.holding_torques(0, f, t);
    EXPECT_LT((got - expected).norm(), 1e-9 * expected.norm()) << got.transpose() << " / " << expected.transpose();
  }
}

TEST(PlatformWorld, MagnetClearanceFromTheTorso) {
  // A supine torso (0.33 × 0.25 m) round the carina at the origin, its top 0.09 m above; a magnet straight above the
  // carina, its axis vertical: the gap is the height of its lower face above the anterior skin at 0.125 m.
  PlatformModel model = supine_patient();
  model.arms.push_back(epm_mount(Iso3::Identity()));
  const PlatformWorld world(model);
  for (const double h : {0.2, 0.25, 0.4}) {
    Iso3 pose = Iso3::Identity();
    pose.linear() = Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()).toRotationMatrix();  // axis along −y... or +y
    pose.translation() = Vec3(0, -h, 0);
    EXPECT_NEAR(world.skin_distance(0, pose), h - 0.0508 - 0.125, 2e-5) << h;
  }
  // Beside the body at the carina's level, its axis along the body: the side gap is the lateral distance less the
  // magnet's radius and the torso's half breadth.
  Iso3 side = Iso3::Identity();
  side.translation() = Vec3(0.30, 0, 0);
  EXPECT_NEAR(world.skin_distance(0, side), 0.30 - 0.0508 - 0.165, 2e-5);
  // Inside: negative.
  side.translation() = Vec3(0.15, 0, 0);
  EXPECT_LT(world.skin_distance(0, side), 0.0);
}

TEST(PlatformWorld, AnArmThroughTheTableCollides) {
  PlatformModel model = supine_patient();
  const Iso3 base = arm_base_beside(*model.body, *model.table, 1, 0.55, 0.1, Vec3::Zero());
  model.arms.push_back(epm_mount(base));
  PlatformWorld world(model);
  JointVector q = JointVector::Zero();  // straight up: clear of everything
  world.set_joints(0, q);
  ArmCheck c = world.check(0);
  EXPECT_FALSE(c.collision) << c.nearest_what << " " << c.nearest;
  q[1] = 100.0 * kDegToRad;  // A2 turned 100° towards the table (its x faces the table): down through the table top
  world.set_joints(0, q);
  c = world.check(0);
  EXPECT_TRUE(c.collision) << c.nearest_what << " " << c.nearest;
}

TEST(PlatformWorld, ArmsWhoseSideFollowsTheTargetCrossToItsSide) {
  // place_arms_for: an arm placed on the target's side (its other side kept) moves to the other side for a target
  // there, and back; an arm whose side the scene fixed stays.
  PlatformModel model = supine_patient();
  const Iso3 right = arm_base_beside(*model.body, *model.table, 1, 0.55, 0.0, Vec3::Zero());
  const Iso3 left = arm_base_beside(*model.body, *model.table, -1, 0.55, 0.0, Vec3::Zero());
  ArmMount m = epm_mount(right);
  m.other_side = left;
  model.arms.push_back(m);
  const Vec3 x = model.body->frame.linear().col(0);
  place_arms_for(model, -0.03 * x);  // a target on the left
  EXPECT_LT((model.arms[0].base.translation() - left.translation()).norm(), 1e-12);
  place_arms_for(model, -0.05 * x);  // still the left: nothing moves
  EXPECT_LT((model.arms[0].base.translation() - left.translation()).norm(), 1e-12);
  place_arms_for(model, 0.03 * x);
  EXPECT_LT((model.arms[0].base.translation() - right.translation()).norm(), 1e-12);
  model.arms[0].other_side.reset();  // the side fixed by the scene
  place_arms_for(model, -0.03 * x);
  EXPECT_LT((model.arms[0].base.translation() - right.translation()).norm(), 1e-12);
}

}  // namespace
}  // namespace magvine::platform
