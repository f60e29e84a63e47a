#include "magvine/platform/arm.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "magvine/core/units.hpp"

namespace magvine::platform {

namespace {

/// URDF origin: translation xyz, rotation R = Rz(yaw)·Ry(pitch)·Rx(roll).
Iso3 urdf_origin(double x, double y, double z, double roll, double pitch, double yaw) {
  Iso3 t = Iso3::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
                Eigen::AngleAxisd(roll, Vec3::UnitX()))
                   .toRotationMatrix();
  t.translation() = Vec3(x, y, z);
  return t;
}

JointVector degrees(double a1, double a2, double a3, double a4, double a5, double a6, double a7) {
  JointVector v;
  v << a1, a2, a3, a4, a5, a6, a7;
  return v * kDegToRad;
}

/// The rotation taking unit a onto unit b as a rotation vector (its angle atan2(|a × b|, a·b)).
Vec3 rotation_between(const Vec3& a, const Vec3& b) {
  const Vec3 c = a.cross(b);
  const double s = c.norm();
  const double angle = std::atan2(s, a.dot(b));
  if (s < 1e-300) return angle < 1.0 ? Vec3::Zero() : Vec3(a.unitOrthogonal() * angle);
  return c * (angle / s);
}

}  // namespace

ArmModel iiwa14_r820() {
  // Kinematics: the joint origins of Drake's iiwa14 model (manipulation/models/iiwa_description, the same in
  // IFL-CAMP's iiwa_stack): base to A2 360 mm, A2–A4 420 mm, A4–A6 400 mm, A6 to the flange 126 mm (KUKA's
  // dimensions; the flange 1.306 m above the base at q = 0). Masses, centres of mass and principal inertias: the same
  // model (KUKA CAD values adjusted for motors and cables by its authors: 30.6 kg, where the CAD links sum to 29.9
  // kg, KUKA's catalogue weight). Capsules: bounds of the housings (our estimate, docs/platform.md).
  ArmModel a;
  a.name = "KUKA LBR iiwa 14 R820";
  a.base = {Iso3::Identity(), 5.0, Vec3(-0.1, 0, 0.07), Vec3(0.05, 0.06, 0.03), Vec3::Zero(), Vec3(0, 0, 0.1575), 0.11};
  const double pi = kPi;
  a.links[0] = {urdf_origin(0, 0, 0.1575, 0, 0, 0),
                5.76,
                Vec3(0, -0.03, 0.12),
                Vec3(0.033, 0.0333, 0.0123),
                Vec3::Zero(),
                Vec3(0, 0, 0.2025),
                0.08};
  a.links[1] = {urdf_origin(0, 0, 0.2025, pi / 2, 0, pi),
                6.35,
                Vec3(0.0003, 0.059, 0.042),
                Vec3(0.0305, 0.0304, 0.011),
                Vec3::Zero(),
                Vec3(0, 0.2045, 0),
                0.08};
  a.links[2] = {urdf_origin(0, 0.2045, 0, pi / 2, 0, pi),
                3.5,
                Vec3(0, 0.03, 0.13),
                Vec3(0.025, 0.0238, 0.0076),
                Vec3::Zero(),
                Vec3(0, 0, 0.2155),
                0.075};
  a.links[3] = {urdf_origin(0, 0, 0.2155, pi / 2, 0, 0),
                3.5,
                Vec3(0, 0.067, 0.034),
                Vec3(0.017, 0.0164, 0.006),
                Vec3::Zero(),
                Vec3(0, 0.1845, 0),
                0.075};
  a.links[4] = {urdf_origin(0, 0.1845, 0, -pi / 2, pi, 0),
                3.5,
                Vec3(0.0001, 0.021, 0.076),
                Vec3(0.01, 0.0087, 0.00449),
                Vec3::Zero(),
                Vec3(0, 0, 0.2155),
                0.07};
  a.links[5] = {urdf_origin(0, 0, 0.2155, pi / 2, 0, 0),
                1.8,
                Vec3(0, 0.0006, 0.0004),
                Vec3(0.0049, 0.0047, 0.0036),
                Vec3::Zero(),
                Vec3(0, 0.081, 0),
                0.07};
  a.links[6] = {urdf_origin(0, 0.081, 0, -pi / 2, pi, 0),
                1.2,
                Vec3(0, 0, 0.02),
                Vec3(0.001, 0.001, 0.001),
                Vec3::Zero(),
                Vec3(0, 0, 0.045),
                0.055};
  a.flange = urdf_origin(0, 0, 0.045, 0, 0, 0);
  // KUKA's data sheet (via Drake's iiwa_description README, "page 30" of the LBR iiwa brochure): axis ranges, speeds
  // and maximum torques. KUKA publishes no acceleration limits: Drake's estimates from measurements (a Chalmers MSc
  // thesis, its table 4).
  a.q_max = degrees(170, 120, 170, 120, 170, 120, 175);
  a.q_min = -a.q_max;
  a.qd_max = degrees(85, 85, 100, 75, 130, 135, 135);
  a.qdd_max << 8.57, 8.57, 8.74, 11.36, 12.23, 15.72, 15.72;
  a.tau_max << 320, 320, 176, 176, 110, 40, 40;
  return a;
}

JointVector random_joints(const ArmModel& arm, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  JointVector q;
  for (int i = 0; i < kArmJoints; ++i) q[i] = arm.q_min[i] + unit(rng) * (arm.q_max[i] - arm.q_min[i]);
  return q;
}

std::array<Iso3, kArmJoints> link_frames(const ArmModel& arm, const Iso3& base, const JointVector& q) {
  std::array<Iso3, kArmJoints> f;
  Iso3 t = base;
  for (int i = 0; i < kArmJoints; ++i) {
    t = t * arm.links[static_cast<std::size_t>(i)].origin * Eigen::AngleAxisd(q[i], Vec3::UnitZ());
    f[static_cast<std::size_t>(i)] = t;
  }
  return f;
}

Iso3 flange_pose(const ArmModel& arm, const Iso3& base, const JointVector& q) {
  return link_frames(arm, base, q).back() * arm.flange;
}

Jacobian point_jacobian(const std::array<Iso3, kArmJoints>& frames, const Vec3& point) {
  Jacobian j;
  for (int i = 0; i < kArmJoints; ++i) {
    const Iso3& f = frames[static_cast<std::size_t>(i)];
    const Vec3 z = f.linear().col(2);
    j.block<3, 1>(0, i) = z.cross(point - f.translation());
    j.block<3, 1>(3, i) = z;
  }
  return j;
}

JointVector holding_torques(const ArmModel& arm, const ArmTool& tool, const Iso3& base, const JointVector& q,
                            const Vec3& gravity, const Vec3& force, const Vec3& torque, const Vec3& point) {
  const std::array<Iso3, kArmJoints> frames = link_frames(arm, base, q);
  JointVector tau = JointVector::Zero();
  // Statics: τ = −Σ_k J_kᵀ w_k over the loads w_k (weights m_k g at the centres of mass, the wrench at `point`), J_k
  // the Jacobian of the point the load acts on: joint i carries −z_i · [(p − o_i) × f + t] of each load beyond it.
  const auto add_load = [&](const Vec3& at, const Vec3& f, const Vec3& t) {  // a load on link 7
    const Jacobian j = point_jacobian(frames, at);
    tau -= j.topRows<3>().transpose() * f + j.bottomRows<3>().transpose() * t;
  };
  for (int k = 0; k < kArmJoints; ++k) {
    const ArmLink& l = arm.links[static_cast<std::size_t>(k)];
    const Iso3& f = frames[static_cast<std::size_t>(k)];
    Jacobian j = point_jacobian(frames, f * l.com);
    j.rightCols(kArmJoints - 1 - k).setZero();  // a link's weight loads only the joints before it
    tau -= j.topRows<3>().transpose() * (l.mass * gravity);
  }
  const Iso3 fl = frames.back() * arm.flange;
  if (tool.mass > 0.0) add_load(fl * tool.com, tool.mass * gravity, Vec3::Zero());
  if (force.squaredNorm() > 0.0 || torque.squaredNorm() > 0.0) add_load(point, force, torque);
  return tau;
}

namespace {

/// The task error (position; orientation as a rotation vector, or only the turn of the z axis) and its Jacobian.
struct TaskError {
  Eigen::Matrix<double, 6, 1> e;
  Jacobian j;
  double position = 0.0;
  double angle = 0.0;
};

TaskError task_error(const ArmModel& arm, const Iso3& base, const Iso3& tool, const Iso3& target, IkTask task,
                     const JointVector& q) {
  const std::array<Iso3, kArmJoints> frames = link_frames(arm, base, q);
  const Iso3 x = frames.back() * arm.flange * tool;
  TaskError t;
  t.j = point_jacobian(frames, x.translation());
  t.e.head<3>() = target.translation() - x.translation();
  Vec3 w;
  if (task == IkTask::kPose) {
    const Eigen::AngleAxisd aa(target.linear() * x.linear().transpose());
    w = aa.axis() * aa.angle();
  } else {
    // Only the axis: the turn that takes z onto the target's z; the turn about z is left free (its Jacobian row is
    // removed by projecting the angular rows onto the plane normal to z).
    const Vec3 z = x.linear().col(2);
    w = rotation_between(z, target.linear().col(2));
    t.j.bottomRows<3>() = (Mat3::Identity() - z * z.transpose()) * t.j.bottomRows<3>();
  }
  t.e.tail<3>() = w;
  t.position = t.e.head<3>().norm();
  t.angle = w.norm();
  return t;
}

}  // namespace

IkResult solve_ik(const ArmModel& arm, const Iso3& base, const Iso3& tool, const Iso3& target, const JointVector& start,
                  const IkOptions& options) {
  std::mt19937_64 rng(options.seed);
  // Rows weighted so that a radian of orientation counts as kLength metres of position.
  constexpr double kLength = 0.3;
  constexpr double kMaxStep = 0.2;  // [rad]
  IkResult best;
  best.position_error = best.angle_error = std::numeric_limits<double>::infinity();
  for (int s = 0; s <= options.restarts; ++s) {
    JointVector q = s > 0 ? random_joints(arm, rng) : start;
    q = q.cwiseMax(arm.q_min).cwiseMin(arm.q_max);
    double lambda = 1e-3;
    TaskError t = task_error(arm, base, tool, target, options.task, q);
    const auto cost = [&](const TaskError& e) {
      return e.e.head<3>().squaredNorm() + kLength * kLength * e.e.tail<3>().squaredNorm();
    };
    for (int it = 0; it < options.iterations; ++it) {
      if (t.position <= options.position_tolerance && t.angle <= options.angle_tolerance) break;
      Jacobian jw = t.j;
      jw.bottomRows<3>() *= kLength;
      Eigen::Matrix<double, 6, 1> ew = t.e;
      ew.tail<3>() *= kLength;
      // Levenberg–Marquardt: accept a step that lowers the error, else damp harder. A joint at a limit that the step
      // would push further is held (its column removed), so the others do the work instead of stalling there.
      bool accepted = false;
      for (int tries = 0; tries < 8 && !accepted; ++tries) {
        JointVector dq = JointVector::Zero();
        std::array<bool, kArmJoints> held{};
        for (int pass = 0; pass < kArmJoints; ++pass) {
          Jacobian jh = jw;
          for (int i = 0; i < kArmJoints; ++i) {
            if (held[static_cast<std::size_t>(i)]) jh.col(i).setZero();
          }
          const Eigen::Matrix<double, 6, 6> a = jh * jh.transpose() + lambda * Eigen::Matrix<double, 6, 6>::Identity();
          dq = jh.transpose() * a.ldlt().solve(ew);
          bool more = false;
          for (int i = 0; i < kArmJoints; ++i) {
            const bool at_min = q[i] <= arm.q_min[i] + 1e-12 && dq[i] < 0.0;
            const bool at_max = q[i] >= arm.q_max[i] - 1e-12 && dq[i] > 0.0;
            if (!held[static_cast<std::size_t>(i)] && (at_min || at_max))
              more = held[static_cast<std::size_t>(i)] = true;
          }
          if (!more) break;
        }
        // A trust region of 0.2 rad per joint keeps the solution on the branch of the start (the nearest posture).
        const double largest = dq.cwiseAbs().maxCoeff();
        if (largest > kMaxStep) dq *= kMaxStep / largest;
        const JointVector trial = (q + dq).cwiseMax(arm.q_min).cwiseMin(arm.q_max);
        const TaskError tt = task_error(arm, base, tool, target, options.task, trial);
        if (cost(tt) < cost(t)) {
          q = trial;
          t = tt;
          lambda = std::max(1e-9, lambda * 0.3);
          accepted = true;
        } else {
          lambda *= 10.0;
        }
      }
      if (!accepted) break;  // a local minimum (often a joint limit): the next start
    }
    const bool ok = t.position <= options.position_tolerance && t.angle <= options.angle_tolerance;
    if (ok ||
        cost(t) < best.position_error * best.position_error + kLength * kLength * best.angle_error * best.angle_error) {
      best.q = q;
      best.position_error = t.position;
      best.angle_error = t.angle;
      best.converged = ok;
    }
    best.starts = s + 1;
    if (ok) break;
  }
  return best;
}

bool track_joints(const ArmModel& arm, const JointVector& goal, double dt, JointVector& q, JointVector& qd) {
  // Synchronised: the remaining motion e is one path; its fraction s ∈ [0, 1] moves under the tightest of the joints'
  // limits scaled by their share, ṡ ≤ V = min v_i/|e_i| and s̈ ≤ A = min a_i/|e_i|, so every joint keeps its limits
  // and, from rest, the joints arrive together along the straight line in joint space (the path the placement was
  // checked along). Each joint then follows the braking law towards its goal under its scaled limits.
  const JointVector e = goal - q;
  double v_scale = std::numeric_limits<double>::infinity(), a_scale = v_scale;
  for (int i = 0; i < kArmJoints; ++i) {
    if (std::abs(e[i]) < 1e-12) continue;
    v_scale = std::min(v_scale, arm.qd_max[i] / std::abs(e[i]));
    a_scale = std::min(a_scale, arm.qdd_max[i] / std::abs(e[i]));
  }
  bool settled = true;
  for (int i = 0; i < kArmJoints; ++i) {
    const double a_max = arm.qdd_max[i];
    const double v_lim = std::isfinite(v_scale) ? std::min(arm.qd_max[i], v_scale * std::abs(e[i])) : 0.0;
    const double a_lim = std::isfinite(a_scale) ? std::min(a_max, a_scale * std::abs(e[i])) : 0.0;
    // The braking law on the remaining distance (discrete: aim to stop on the goal; the last step lands on it).
    double want = std::copysign(std::min(v_lim, std::sqrt(2.0 * a_lim * std::abs(e[i]))), e[i]);
    if (std::abs(e[i]) <= std::max(a_lim, 1e-12) * dt * dt) want = e[i] / dt;
    // A joint still moving from an earlier goal brakes within its own limit.
    const double v = std::clamp(want, qd[i] - a_max * dt, qd[i] + a_max * dt);
    q[i] = std::clamp(q[i] + v * dt, arm.q_min[i], arm.q_max[i]);
    qd[i] = v;
    if (std::abs(goal[i] - q[i]) > 1e-9 || std::abs(v) > a_max * dt) settled = false;
  }
  return settled;
}

}  // namespace magvine::platform
