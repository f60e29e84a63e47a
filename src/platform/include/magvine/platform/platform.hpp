#pragma once
/// The magnetic manipulation platform (issue 30, docs/platform.md): the patient's torso and the table around the
/// airway, and one or two arms each holding an EPM, as a Bullet rigid-body world (double precision) beside the soft
/// robot. The model is immutable (PlatformModel); a run owns a PlatformWorld (the Bullet objects, which move) and a
/// PlatformState (the arms' joints and what the run has measured of them).
///
/// The arms are kinematic: each step the joint tracker (arm.hpp) moves the joints within their velocity and
/// acceleration limits and Bullet's articulated bodies and colliders follow; the KUKA's own joint position control
/// tracks to well under a millimetre at these speeds, which is below what the field resolves. Bullet answers the
/// contact questions (GJK/EPA signed distances between the convex colliders: links, magnets, torso, table) and the
/// holding torques (the articulated-body algorithm of btMultiBody, inverted at rest).

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "magvine/core/eigen_types.hpp"
#include "magvine/platform/arm.hpp"

namespace magvine::platform {

/// The patient's torso: an elliptic cylinder. Frame: origin at its centre, x to the patient's left–right, y
/// anterior (up for a supine patient), z towards the head.
struct TorsoModel {
  Iso3 frame = Iso3::Identity();
  double breadth = 0.33;  ///< left–right [m]
  double depth = 0.25;    ///< anterior–posterior [m]
  double length = 0.60;   ///< shoulders to hips [m]
};

/// The table: a box whose top face the patient lies on. Frame: origin at the centre of the top face, z up, x across.
struct TableModel {
  Iso3 frame = Iso3::Identity();
  double width = 0.50;      ///< [m]
  double length = 2.0;      ///< [m]
  double thickness = 0.05;  ///< [m]
};

/// One arm of the platform and the magnet it holds.
struct ArmMount {
  Iso3 base = Iso3::Identity();  ///< world ← the arm's base (z up through A1)
  int magnet = 0;                ///< index in the scene's magnets
  ArmTool tool;                  ///< where the magnet sits on the flange (z: its axis)
  double magnet_radius = 0.0508; ///< [m]
  double magnet_length = 0.1016; ///< [m]
  JointVector home = JointVector::Zero();  ///< the posture the redundancy leans towards [rad]
};

struct PlatformModel {
  ArmModel arm = iiwa14_r820();
  std::optional<TorsoModel> body;
  std::optional<TableModel> table;
  std::vector<ArmMount> arms;
  double clearance = 0.01;  ///< the least distance between a magnet and the skin [m]
  Vec3 gravity = Vec3(0, 0, -9.81);
};

/// The torso and table around an airway: the torso's long axis along −`caudal` (the trachea's direction), its
/// anterior along `up`; the carina at mid-depth on the midline, `above_carina` below the torso's top; the table's top
/// under the torso's back. Dimensions from `torso` and `table` (their frames are set here).
void place_patient(const Vec3& carina, const Vec3& caudal, const Vec3& up, double above_carina, TorsoModel& torso,
                   TableModel* table);

/// The base of an arm standing beside the table: on the patient's `side` (+1: the +x of the torso frame, −1: the
/// other), `lateral` from the midline, its base `below_top` under the table's top, level with `at` along the body,
/// A1 up and its x axis facing the table.
Iso3 arm_base_beside(const TorsoModel& torso, const TableModel& table, int side, double lateral, double below_top,
                     const Vec3& at);

/// What a check of an arm's configuration found.
struct ArmCheck {
  double skin_clearance = 0.0;  ///< signed distance between its magnet and the torso [m] (∞ without a torso)
  double nearest = 0.0;         ///< least signed distance between any of its links or its magnet and the torso,
                                ///< table or the other arm [m]
  std::string nearest_what;     ///< which pair
  bool collision = false;       ///< nearest < 0
};

/// The Bullet world of one run: btMultiBodyDynamicsWorld holding the torso and table (static colliders) and each arm
/// as a fixed-base btMultiBody with a capsule collider per link and a cylinder for its magnet.
class PlatformWorld {
 public:
  explicit PlatformWorld(const PlatformModel& model);
  ~PlatformWorld();
  PlatformWorld(const PlatformWorld&) = delete;
  PlatformWorld& operator=(const PlatformWorld&) = delete;

  /// Moves arm `arm`'s joints (and its colliders) to q.
  void set_joints(int arm, const JointVector& q);
  /// The checks at the arms' current joints.
  ArmCheck check(int arm) const;
  /// The signed distance from a magnet of arm `arm`'s size at `magnet_pose` (z: its axis) to the torso (∞ without one).
  double skin_distance(int arm, const Iso3& magnet_pose) const;
  /// The collider transforms Bullet holds for arm `arm`'s links (world ← link frame; for tests of the frames).
  std::array<Iso3, kArmJoints> bullet_link_frames(int arm) const;
  /// The joint torques that hold arm `arm` still at its current joints against gravity, its magnet's weight and a
  /// wrench on its magnet (force; torque about the magnet's centre), by Bullet's articulated-body algorithm: the
  /// accelerations at rest are affine in the torques, a(τ) = A τ + a0, and τ = −A⁻¹ a0 makes them zero.
  JointVector holding_torques(int arm, const Vec3& force = Vec3::Zero(), const Vec3& torque = Vec3::Zero());

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

/// The magnet's frame (z: its axis) of arm `mount` at joints q.
Iso3 magnet_pose(const ArmModel& arm, const ArmMount& mount, const JointVector& q);

}  // namespace magvine::platform
