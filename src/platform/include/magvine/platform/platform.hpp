#pragma once
/// The magnetic manipulation platform (issue 30, docs/platform.md): the patient's torso and the table around the
/// airway, and one or two arms each holding an EPM, as a Bullet rigid-body world (double precision) beside the soft
/// robot. The model is immutable (PlatformModel); a run owns a PlatformRun: the Bullet objects, which move
/// (PlatformWorld), the arms' joints, goals and what the run has measured of them.
///
/// The arms are kinematic: each step the joint tracker (arm.hpp) moves the joints within their velocity and
/// acceleration limits and Bullet's articulated bodies and colliders follow; the KUKA's own joint position control
/// tracks to well under a millimetre at these speeds, which is below what the field resolves. Bullet answers the
/// contact questions (GJK/EPA signed distances between the convex colliders: links, magnets, torso, table) and the
/// holding torques (the articulated-body algorithm of btMultiBody, inverted at rest).

#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
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
  Iso3 base = Iso3::Identity();            ///< world ← the arm's base (z up through A1)
  int magnet = 0;                          ///< index in the scene's magnets
  ArmTool tool;                            ///< where the magnet sits on the flange (z: its axis)
  double magnet_radius = 0.0508;           ///< [m]
  double magnet_length = 0.1016;           ///< [m]
  JointVector home = JointVector::Zero();  ///< the posture it starts in, and a start of its IK [rad]
  /// Where it would stand on the patient's other side, when its side follows the target (place_arms_for);
  /// none when the scene fixed its side.
  std::optional<Iso3> other_side;
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

/// Puts the arms whose side follows the target (ArmMount::other_side) so that the first stands on `target`'s side of
/// the torso, a second on the other (a trial aimed at another branch than the scene's).
void place_arms_for(PlatformModel& model, const Vec3& target);

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
  /// The signed distance from a magnet of arm `arm`'s size at `magnet_pose` (z: its axis) to the torso (∞ without one);
  /// without `depth`, an overlap is −1 (not measured: cheaper).
  double skin_distance(int arm, const Iso3& magnet_pose, bool depth = true) const;
  /// The same to the table (∞ without one; an overlap −1).
  double table_distance(int arm, const Iso3& magnet_pose) const;
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

/// Whether an arm can hold its magnet at a pose, and how.
struct Placement {
  bool feasible = false;
  JointVector q = JointVector::Zero();  ///< the joints that do it (the best found when not feasible)
  /// Joints to pass through first, in order: where the straight way would come too near the patient, the arm backs
  /// its magnet out from the torso, moves round, and comes in again.
  std::vector<JointVector> via;
  Vec3 position = Vec3::Zero();  ///< the magnet's centre placed [m]
  Vec3 axis = Vec3::UnitZ();     ///< its axis
  std::string why;               ///< what makes it infeasible: unreachable, a collision, too near the skin
};

/// What a run measured of the arms (metrics.json: manipulators and the keys below, docs/platform.md).
struct PlatformFigures {
  double min_skin_clearance = std::numeric_limits<double>::infinity();  ///< magnet to skin, every step [m]
  int collisions = 0;                ///< steps at which a link or magnet touched the torso, table or other arm
  int limit_violations = 0;          ///< steps with a joint beyond its position, velocity or acceleration limit
  double max_torque_fraction = 0.0;  ///< largest |τ_i| / τ_max,i over the steps (holding torques)
  double path_length = 0.0;          ///< Σ over arms and joints of the joint travel [rad]
  double max_tracking_error = 0.0;   ///< largest distance between the magnet's (feasible) pose asked for and the one
                                     ///< reached, every step: the arm's lag [m]
  double compute_s = 0.0;            ///< computing spent on the arms and on placing magnets through them [s]
};

/// One arm's joints at a time (arms.csv).
struct ArmSample {
  double time = 0.0;
  int arm = 0;
  JointVector q = JointVector::Zero();
  JointVector tau = JointVector::Zero();  ///< holding torques [N·m]
  Vec3 magnet = Vec3::Zero();             ///< the magnet's centre [m]
};

/// The platform during a run: the Bullet world, each arm's joints, velocities and goal, and the figures. Each step:
/// request() the magnets' poses when they change (IK, the checks, the nearest feasible pose), advance() the arms,
/// then read magnet_pose() for the field.
class PlatformRun {
 public:
  explicit PlatformRun(const PlatformModel& model);

  /// Whether arm `arm` can hold its magnet at (position, axis): inverse kinematics (position and axis; the turn about
  /// the axis is free) from the arm's joints (with `near_only`, only a solution within 20° a joint of them), then
  /// (unless `near_only`) from its home and random starts; a solution is feasible when the arm there, and on its way
  /// there from where it is (the joint tracker's motion from the arm's joints and speeds at the run's step, checked
  /// every 0.05 rad), touches nothing and keeps its magnet the clearance from the skin. `either_way`: the axis's sign
  /// does not matter (a soft-magnetic fill): −axis is tried first, then axis. Does not move the arm.
  Placement evaluate(int arm, const Vec3& position, const Vec3& axis, bool near_only = false, bool either_way = false);
  /// The least distance along `line` from `from` at which arm `arm`'s magnet (axis `axis`) clears the skin by the
  /// model's clearance plus `margin`, at least `min_distance` [m]; ∞ when not within `max_distance` or where the
  /// magnet would meet the table.
  double clear_distance(int arm, const Vec3& from, const Vec3& line, const Vec3& axis, double min_distance,
                        double max_distance, double margin = 0.0) const;
  /// The magnet's centre on the shell round the torso where it clears the skin by the clearance: out from the
  /// torso's axis at `level` (along the torso's z from its centre [m]) in the direction at `angle` in the torso's
  /// x–y plane (0: x, π/2: y, anterior), at the least distance that clears (with 3 mm to spare, so that the way
  /// between nearby shell points keeps the clearance) with the magnet's axis along `axis`
  /// (default: that direction), `level` kept over the torso (its length less the magnet's: neck, head and legs are not
  /// modelled), then `standoff` [m] further out. None without a torso, or where the magnet would meet the table.
  std::optional<Vec3> shell_point(int arm, double angle, double level, const Vec3* axis = nullptr,
                                  double standoff = 0.0) const;
  /// `level` kept over the torso as shell_point keeps it.
  double shell_level(int arm, double level) const;
  /// The outward direction at `angle` (the torso's x–y plane; zero without a torso).
  Vec3 shell_direction(double angle) const;
  /// A point's (angle, level) in those terms.
  std::pair<double, double> shell_coordinates(const Vec3& x) const;
  /// Asks arm `arm` for its magnet at (position, axis): the goal becomes the request when feasible, otherwise the
  /// nearest feasible pose (moved away from the torso, then searched around) — returned with `why` set (a workspace
  /// event for the caller). `start`: the arm is there now (the run's first pose), no motion.
  Placement request(int arm, const Vec3& position, const Vec3& axis, bool start = false);
  /// Sends the arm to a placement evaluate() found feasible (through its via joints).
  void set_goal(int arm, const Placement& placement);
  /// The time it needs to finish the way it is on, at its joints' top speeds (the slowest joint's on each leg) [s].
  double remaining_time(int arm) const;
  /// Puts the arm at its goal at once (the run's first pose: the arm is there before the run starts).
  void jump_to_goal(int arm);
  /// Moves every arm one step of dt towards its goal (joint tracker), updates the world and the figures; `wrench`
  /// (called once the arms have moved) gives per arm the force [N] and torque about its centre [N·m] on its magnet
  /// (another magnet's), for the holding torques.
  void advance(double time, double dt, const std::function<std::vector<std::pair<Vec3, Vec3>>()>& wrench);
  /// A further check of an arm at joints q, with the others where they are (e.g. the dEPM pair's torques): why the
  /// pose is not allowed, or empty. Applied wherever evaluate() checks a pose or a way.
  using PoseCheck = std::function<std::string(int arm, const JointVector& q)>;
  void set_pose_check(PoseCheck check) { m_pose_check = std::move(check); }
  /// The holding torques of arm `arm` at joints q (not where it is) against gravity and a wrench on its magnet
  /// (force; torque about its centre), by Bullet's articulated bodies (PlatformWorld::holding_torques).
  JointVector holding_torques_at(int arm, const JointVector& q, const Vec3& force, const Vec3& torque);
  /// A link's collision capsule in the world.
  struct Capsule {
    Vec3 a, b;
    double radius;
  };
  /// Every arm's capsules where the arms are now (the foot and links 1–7; for drawing).
  std::vector<Capsule> link_capsules() const;
  /// The magnet's pose the arm has reached.
  Iso3 magnet_pose(int arm) const;
  const JointVector& joints(int arm) const { return m_arms[static_cast<std::size_t>(arm)].q; }
  int arm_of_magnet(int magnet) const;
  /// The side of the patient arm `arm` stands on: the torso's ±x (zero without a torso).
  Vec3 arm_side(int arm) const;
  const PlatformFigures& figures() const { return m_figures; }
  const std::vector<ArmSample>& samples() const { return m_samples; }
  const PlatformModel& model() const { return m_model; }

 private:
  struct ArmState {
    JointVector q = JointVector::Zero();
    JointVector qd = JointVector::Zero();
    JointVector goal = JointVector::Zero();  ///< the joints it moves to now
    std::vector<JointVector> next;           ///< and then (a placement's via joints, then its own)
    Vec3 asked = Vec3::Zero();               ///< the magnet's centre last asked for
    bool placed = false;                     ///< the run has put it at its first pose (before: no way there to check)
  };
  Placement nearest_feasible(int arm, const Vec3& position, const Vec3& axis);
  /// Why the tracker's way from where the arm is through `legs` (joints in order) is not clear, or empty.
  std::string way_problem(int arm, const std::vector<JointVector>& legs);
  /// Why the arm at q would collide or bring its magnet within the clearance, or empty. Leaves the world at q.
  std::string pose_problem(int arm, const JointVector& q);

  const PlatformModel& m_model;
  PlatformWorld m_world;
  std::vector<ArmState> m_arms;
  PlatformFigures m_figures;
  std::vector<ArmSample> m_samples;
  PoseCheck m_pose_check;
  double m_dt = 0.02;  ///< the run's step (the last advance()'s), for predicting the tracker's way [s]
};

}  // namespace magvine::platform
