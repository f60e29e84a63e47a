#pragma once
/// A serial manipulator holding an EPM: its kinematic and inertial model (the KUKA LBR iiwa 14 R820 with its
/// published data), forward kinematics, the geometric Jacobian, gravity and wrench torques, inverse kinematics and a
/// velocity- and acceleration-limited joint tracker. Pure Eigen; the Bullet world around the arms is
/// platform_world.hpp. Model and data: docs/platform.md.

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <random>
#include <string>

#include "magvine/core/eigen_types.hpp"

namespace magvine::platform {

inline constexpr int kArmJoints = 7;
using JointVector = Eigen::Matrix<double, kArmJoints, 1>;
using Iso3 = Eigen::Isometry3d;
using Jacobian = Eigen::Matrix<double, 6, kArmJoints>;  ///< rows: linear velocity, angular velocity (world)

/// One link: the fixed transform from the parent link's frame to its joint (a revolute joint about the joint
/// frame's z), then the link's frame turned by the joint angle. URDF convention.
struct ArmLink {
  Iso3 origin = Iso3::Identity();  ///< parent frame → joint frame at q = 0
  double mass = 0.0;               ///< [kg]
  Vec3 com = Vec3::Zero();         ///< centre of mass in the link frame [m]
  Vec3 inertia = Vec3::Zero();     ///< principal moments about the centre of mass, link axes [kg·m²]
  /// The collision capsule in the link frame: segment a–b, radius [m] (a bound of the link's housing).
  Vec3 capsule_a = Vec3::Zero();
  Vec3 capsule_b = Vec3::Zero();
  double capsule_radius = 0.0;
};

/// The EPM on the flange: where its centre and magnetisation axis sit in the flange frame, and its mass.
struct ArmTool {
  Iso3 flange_to_magnet = Iso3::Identity();  ///< the magnet's frame (z: its axis) in the flange frame
  double mass = 0.0;                         ///< magnet and holder [kg]
  Vec3 com = Vec3::Zero();                   ///< in the flange frame [m]
};

/// An arm: the base link's capsule, seven links, the flange, the limits (the data sheet's).
struct ArmModel {
  std::string name;
  ArmLink base;                           ///< link 0 (fixed): mass and capsule only
  std::array<ArmLink, kArmJoints> links;  ///< links 1..7
  Iso3 flange = Iso3::Identity();         ///< link 7 frame → flange
  JointVector q_min, q_max;               ///< [rad]
  JointVector qd_max;                     ///< [rad/s]
  JointVector qdd_max;                    ///< [rad/s²]
  JointVector tau_max;                    ///< [N·m]
};

/// The KUKA LBR iiwa 14 R820 (docs/platform.md cites the sources of every number).
ArmModel iiwa14_r820();

/// A joint vector drawn uniformly within the limits (the IK's random starts).
JointVector random_joints(const ArmModel& arm, std::mt19937_64& rng);

/// World frames of links 1..7 at joint angles q, the base at `base` (world ← base link frame).
std::array<Iso3, kArmJoints> link_frames(const ArmModel& arm, const Iso3& base, const JointVector& q);
/// The flange in the world.
Iso3 flange_pose(const ArmModel& arm, const Iso3& base, const JointVector& q);

/// The geometric Jacobian of a point fixed to link 7 (world coordinates `point`), from the link frames: column i is
/// [z_i × (p − o_i); z_i] with z_i, o_i joint i's axis and origin.
Jacobian point_jacobian(const std::array<Iso3, kArmJoints>& frames, const Vec3& point);

/// The joint torques that hold the arm still against gravity g [m/s²] (world) and a wrench (force, torque about
/// `point`) applied to link 7 at `point`: τ = Σ_i J_ci,vᵀ (−m_i g) − Jᵀ [f; t] (statics: τ balances the loads), with
/// the tool's mass on link 7.
JointVector holding_torques(const ArmModel& arm, const ArmTool& tool, const Iso3& base, const JointVector& q,
                            const Vec3& gravity, const Vec3& force = Vec3::Zero(), const Vec3& torque = Vec3::Zero(),
                            const Vec3& point = Vec3::Zero());

/// What the inverse kinematics must match: the full pose of the tool frame, or its position and z axis (a magnet's
/// field is symmetric about its axis, so the turn about it is free and joins the redundancy).
enum class IkTask { kPose, kPositionAxis };

struct IkOptions {
  IkTask task = IkTask::kPose;
  double position_tolerance = 1e-6;  ///< [m]
  double angle_tolerance = 1e-5;     ///< [rad]
  int iterations = 100;              ///< per start
  int restarts = 40;                 ///< random starts after the given one
  std::uint64_t seed = 1;            ///< of the random starts (deterministic)
};

struct IkResult {
  JointVector q = JointVector::Zero();
  double position_error = 0.0;  ///< [m]
  double angle_error = 0.0;     ///< [rad]
  bool converged = false;
  int starts = 0;  ///< starts tried
};

/// Joint angles within the limits that put the tool frame (flange · `tool`) at `target`: damped least squares
/// (Levenberg–Marquardt on the task error; a joint at a limit the step would push further is held; steps of at most
/// 0.2 rad a joint, so the solution stays on the start's branch: the redundancy keeps the posture nearest the start)
/// from `start`, then from random joint vectors; the first start that converges wins.
IkResult solve_ik(const ArmModel& arm, const Iso3& base, const Iso3& tool, const Iso3& target, const JointVector& start,
                  const IkOptions& options = {});

/// One control step of the joint tracker: the joints move towards `goal` together (each joint's limits scaled by its
/// share of the remaining motion, so that from rest they follow the straight line in joint space) as fast as the
/// velocity and acceleration limits allow, braking in time to stop there (v_wanted = sign(e)·min(v, √(2 a |e|)),
/// velocity changed by at most a_max·dt, positions kept within the limits). `q`, `qd` updated in place; returns
/// whether every joint is at its goal and at rest.
bool track_joints(const ArmModel& arm, const JointVector& goal, double dt, JointVector& q, JointVector& qd);

}  // namespace magvine::platform
