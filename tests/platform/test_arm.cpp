// The LBR iiwa 14 R820 model (platform/arm.hpp): forward kinematics against KUKA's published dimensions, the inverse
// kinematics over random reachable poses, gravity torques against a hand calculation and the joint tracker's limits.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "magvine/core/units.hpp"
#include "magvine/platform/arm.hpp"

namespace magvine::platform {
namespace {

JointVector deg(double a1, double a2, double a3, double a4, double a5, double a6, double a7) {
  JointVector v;
  v << a1, a2, a3, a4, a5, a6, a7;
  return v * kDegToRad;
}

// KUKA's dimensions: A1 foot to A2 360 mm, A2–A4 420 mm, A4–A6 400 mm, A6 to the flange 126 mm.
constexpr double kD1 = 0.360, kD3 = 0.420, kD5 = 0.400, kD7 = 0.126;

TEST(IiwaKinematics, FlangeAtPublishedDimensions) {
  const ArmModel arm = iiwa14_r820();
  const Iso3 base = Iso3::Identity();
  // Zero: straight up, 1.306 m, the flange frame parallel to the base's.
  Iso3 f = flange_pose(arm, base, JointVector::Zero());
  EXPECT_NEAR((f.translation() - Vec3(0, 0, kD1 + kD3 + kD5 + kD7)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((f.linear() - Mat3::Identity()).norm(), 0.0, 1e-12);
  // A2 at +90° (its axis is the base's +y at zero): the arm lies along +x, 946 mm from A2, the flange facing +x.
  f = flange_pose(arm, base, deg(0, 90, 0, 0, 0, 0, 0));
  EXPECT_NEAR((f.translation() - Vec3(kD3 + kD5 + kD7, 0, kD1)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((f.linear().col(2) - Vec3::UnitX()).norm(), 0.0, 1e-12);
  // A4 at +90° (its axis is −y at zero): the forearm and hand turn towards −x from the elbow 780 mm up.
  f = flange_pose(arm, base, deg(0, 0, 0, 90, 0, 0, 0));
  EXPECT_NEAR((f.translation() - Vec3(-(kD5 + kD7), 0, kD1 + kD3)).norm(), 0.0, 1e-12);
  // A1 at 90° turns the A2 case about z: the arm along +y. A6 at −90° (axis +y) then bends the hand 126 mm down.
  f = flange_pose(arm, base, deg(90, 90, 0, 0, 0, -90, 0));
  EXPECT_NEAR((f.translation() - Vec3(0, kD3 + kD5, kD1 + kD7)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((f.linear().col(2) - Vec3::UnitZ()).norm(), 0.0, 1e-12);
}

TEST(IiwaKinematics, InverseKinematicsReachesRandomPoses) {
  // Issue 30: 1000 random reachable poses (forward kinematics of random joint vectors within the limits) reached to
  // 0.1 mm and 0.1° in ≥ 99.5 %, none outside the limits. Each solve starts from the zero posture.
  const ArmModel arm = iiwa14_r820();
  const Iso3 base = Iso3::Identity();
  const Iso3 tool = Iso3::Identity();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int reached = 0, outside = 0, starts = 0;
  constexpr int kPoses = 1000;
  for (int n = 0; n < kPoses; ++n) {
    JointVector q;
    for (int i = 0; i < kArmJoints; ++i) q[i] = arm.q_min[i] + unit(rng) * (arm.q_max[i] - arm.q_min[i]);
    const Iso3 target = flange_pose(arm, base, q);
    IkOptions options;
    options.seed = static_cast<std::uint64_t>(n + 1);
    const IkResult r = solve_ik(arm, base, tool, target, JointVector::Zero(), options);
    starts += r.starts;
    const Iso3 got = flange_pose(arm, base, r.q);
    const double dp = (got.translation() - target.translation()).norm();
    const double da = Eigen::AngleAxisd(got.linear() * target.linear().transpose()).angle();
    if (dp <= 1e-4 && da <= 0.1 * kDegToRad) ++reached;
    for (int i = 0; i < kArmJoints; ++i) outside += (r.q[i] < arm.q_min[i] || r.q[i] > arm.q_max[i]) ? 1 : 0;
  }
  std::printf("IK: %d of %d reached (0.1 mm, 0.1 deg), %.2f starts per solve\n", reached, kPoses,
              static_cast<double>(starts) / kPoses);
  EXPECT_GE(reached, 995);
  EXPECT_EQ(outside, 0);
}

TEST(IiwaKinematics, PositionAndAxisTaskLeavesTheTurnFree) {
  const ArmModel arm = iiwa14_r820();
  const Iso3 base = Iso3::Identity();
  Iso3 tool = Iso3::Identity();
  tool.translation() = Vec3(0, 0, 0.1008);  // a magnet's centre ahead of the flange
  Iso3 target = Iso3::Identity();
  target.translation() = Vec3(0.5, 0.2, 0.3);
  target.linear() = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), Vec3(0, 0, -1)).toRotationMatrix();
  IkOptions options;
  options.task = IkTask::kPositionAxis;
  const IkResult r = solve_ik(arm, base, tool, target, JointVector::Zero(), options);
  ASSERT_TRUE(r.converged);
  const Iso3 got = flange_pose(arm, base, r.q) * tool;
  EXPECT_LT((got.translation() - target.translation()).norm(), 1e-6);
  EXPECT_LT((got.linear().col(2) - Vec3(0, 0, -1)).norm(), 1e-5);
}

TEST(IiwaStatics, GravityTorquesAtAStretchedPose) {
  // A2 at 90°: the arm lies horizontal along +x (A2's axis is +y; the turn takes the base's z onto x), so a point
  // at height z above the foot at q = 0 lies z − 0.36 m from A2 along +x. By hand from the model's centres of mass
  // (Drake's iiwa14 link frames: link 2's y, link 3's z, link 4's y, link 5's z, link 6's y and link 7's z point up
  // the arm at q = 0): each link's weight times that distance, plus a 6.18 kg magnet 0.1508 m beyond the flange.
  const ArmModel arm = iiwa14_r820();
  ArmTool tool;
  tool.mass = 6.18;
  tool.com = Vec3(0, 0, 0.1508);
  const double g = 9.81;
  // Centres of mass along +x from A2 (the link's own offset along the arm, from the model's COM table):
  const double x2 = 0.059;                         // link 2: origin at A2, y 0.059
  const double x3 = 0.2045 + 0.13;                 // link 3: origin 0.2045 past A2, z 0.13
  const double x4 = 0.420 + 0.067;                 // link 4: origin at A4, y 0.067
  const double x5 = 0.420 + 0.1845 + 0.076;        // link 5: origin 0.1845 past A4, z 0.076
  const double x6 = 0.420 + 0.400 + 0.0006;        // link 6: origin at A6, y 0.0006
  const double x7 = 0.420 + 0.400 + 0.081 + 0.02;  // link 7: origin 0.081 past A6, z 0.02
  const double xt = 0.420 + 0.400 + 0.126 + 0.1508;
  const double expected = g * (6.35 * x2 + 3.5 * x3 + 3.5 * x4 + 3.5 * x5 + 1.8 * x6 + 1.2 * x7 + 6.18 * xt);
  const JointVector tau = holding_torques(arm, tool, Iso3::Identity(), deg(0, 90, 0, 0, 0, 0, 0), Vec3(0, 0, -g));
  std::printf("stretched: joint 2 holds %.3f N·m (hand %.3f), limit %.0f\n", tau[1], expected, arm.tau_max[1]);
  // Gravity turns the arm on about +y (x towards −z, the way A2's positive turn goes): the holding torque is −Σ.
  EXPECT_NEAR(tau[1], -expected, 1e-9 * expected);
  // A4's axis stays −y at this pose: it holds the forearm, +Σ m g (x − 0.42) over the links beyond the elbow.
  const double expected4 =
      g * (3.5 * (x4 - 0.42) + 3.5 * (x5 - 0.42) + 1.8 * (x6 - 0.42) + 1.2 * (x7 - 0.42) + 6.18 * (xt - 0.42));
  EXPECT_NEAR(tau[3], expected4, 1e-9 * expected4);
}

TEST(IiwaControl, TrackerKeepsVelocityAndAccelerationLimits) {
  const ArmModel arm = iiwa14_r820();
  JointVector q = JointVector::Zero(), qd = JointVector::Zero();
  const JointVector goal = deg(90, -60, 45, 100, -120, 80, 170);
  const double dt = 0.01;
  bool settled = false;
  double t = 0.0;
  JointVector prev = qd;
  while (!settled && t < 10.0) {
    settled = track_joints(arm, goal, dt, q, qd);
    t += dt;
    for (int i = 0; i < kArmJoints; ++i) {
      ASSERT_LE(std::abs(qd[i]), arm.qd_max[i] * (1 + 1e-12));
      ASSERT_LE(std::abs(qd[i] - prev[i]) / dt, arm.qdd_max[i] * (1 + 1e-9));
    }
    prev = qd;
  }
  EXPECT_TRUE(settled);
  EXPECT_LT((q - goal).norm(), 1e-9);
  // The slowest joint's time-optimal rest-to-rest time: A7, 170° at 135°/s and 15.72 rad/s² → Δ/v + v/a.
  const double t7 = 170.0 / 135.0 + 135.0 * kDegToRad / 15.72;
  const double t5 = 120.0 / 130.0 + 130.0 * kDegToRad / 12.23;
  const double t4 = 100.0 / 75.0 + 75.0 * kDegToRad / 11.36;
  const double t_min = std::max({t7, t5, t4});
  EXPECT_GT(t, t_min - 2 * dt);
  EXPECT_LT(t, t_min + 0.2);
}

}  // namespace
}  // namespace magvine::platform
