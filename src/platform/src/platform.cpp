#include "magvine/platform/platform.hpp"

#include <BulletCollision/NarrowPhaseCollision/btGjkEpaPenetrationDepthSolver.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkPairDetector.h>
#include <BulletCollision/NarrowPhaseCollision/btPointCollector.h>
#include <BulletCollision/NarrowPhaseCollision/btVoronoiSimplexSolver.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#include <btBulletDynamicsCommon.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include "magvine/core/units.hpp"

namespace magvine::platform {

namespace {

static_assert(sizeof(btScalar) == sizeof(double), "magvine links Bullet in double precision only");

btVector3 bt(const Vec3& v) {
  return {v.x(), v.y(), v.z()};
}
Vec3 eig(const btVector3& v) {
  return {v.x(), v.y(), v.z()};
}

btTransform bt(const Iso3& t) {
  const Eigen::Quaterniond q(t.linear());
  return btTransform(btQuaternion(q.x(), q.y(), q.z(), q.w()), bt(Vec3(t.translation())));
}

Iso3 eig(const btTransform& t) {
  const btQuaternion r = t.getRotation();
  Iso3 out = Iso3::Identity();
  out.linear() = Eigen::Quaterniond(r.w(), r.x(), r.y(), r.z()).toRotationMatrix();
  out.translation() = eig(t.getOrigin());
  return out;
}

/// A capsule between a and b (radius r) as a z-capsule and its placement in the frame a and b are given in.
Iso3 capsule_placement(const Vec3& a, const Vec3& b) {
  Iso3 t = Iso3::Identity();
  t.translation() = 0.5 * (a + b);
  const Vec3 d = b - a;
  if (d.norm() > 1e-12) t.linear() = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), d).toRotationMatrix();
  return t;
}

/// The small margin Bullet's GJK keeps round the core of a shape; the shapes are built so their outer surface is
/// the true one (cylinders and boxes subtract it; the torso's core is shrunk by it).
constexpr double kMargin = 5e-4;

/// Signed distance between two convex shapes (negative: penetration depth, by EPA). Without `depth` the penetration
/// is not measured (GJK alone, far cheaper): any overlap returns −1.
double signed_distance(const btConvexShape& a, const btTransform& ta, const btConvexShape& b, const btTransform& tb,
                       bool depth = true) {
  btVoronoiSimplexSolver simplex;
  btGjkEpaPenetrationDepthSolver epa;
  btGjkPairDetector gjk(&a, &b, &simplex, depth ? &epa : nullptr);
  btGjkPairDetector::ClosestPointInput in;
  in.m_transformA = ta;
  in.m_transformB = tb;
  btPointCollector out;
  gjk.getClosestPoints(in, out, nullptr);
  if (!out.m_hasResult) return depth ? std::numeric_limits<double>::infinity() : -1.0;
  return out.m_distance;
}

/// The torso as Bullet sees it: an elliptic cylinder (semi-axes a, b in x and y, half length h along z) with its
/// support mapping in closed form (the point of the ellipse farthest along d is (a² d_x, b² d_y)/√(a² d_x² + b² d_y²)),
/// so GJK costs the same as for a box. The core is shrunk by the margin GJK adds back.
class EllipticCylinderShape : public btConvexInternalShape {
 public:
  EllipticCylinderShape(double a, double b, double h) : m_a(a - kMargin), m_b(b - kMargin), m_h(h - kMargin) {
    m_shapeType = CUSTOM_CONVEX_SHAPE_TYPE;
    setMargin(kMargin);
  }
  btVector3 localGetSupportingVertexWithoutMargin(const btVector3& d) const override {
    const double ex = m_a * m_a * d.x(), ey = m_b * m_b * d.y();
    const double n = std::sqrt(ex * d.x() + ey * d.y());
    const double z = d.z() >= 0.0 ? m_h : -m_h;
    if (n < 1e-300) return {m_a, 0.0, z};
    return {ex / n, ey / n, z};
  }
  void batchedUnitVectorGetSupportingVertexWithoutMargin(const btVector3* vectors, btVector3* out,
                                                         int count) const override {
    for (int i = 0; i < count; ++i) out[i] = localGetSupportingVertexWithoutMargin(vectors[i]);
  }
  void calculateLocalInertia(btScalar, btVector3& inertia) const override { inertia.setZero(); }  // static
  const char* getName() const override { return "EllipticCylinder"; }
  void getAabb(const btTransform& t, btVector3& lo, btVector3& hi) const override { getAabbSlow(t, lo, hi); }

 private:
  double m_a, m_b, m_h;
};

}  // namespace

void place_patient(const Vec3& carina, const Vec3& caudal, const Vec3& up, double above_carina, TorsoModel& torso,
                   TableModel* table) {
  const Vec3 y = up.normalized();
  Vec3 z = -caudal;
  z -= z.dot(y) * y;
  z = z.norm() > 1e-6 ? Vec3(z.normalized()) : Vec3(y.unitOrthogonal());  // a trachea along the vertical: any

  const Vec3 x = y.cross(z);
  torso.frame = Iso3::Identity();
  torso.frame.linear().col(0) = x;
  torso.frame.linear().col(1) = y;
  torso.frame.linear().col(2) = z;
  // The carina at mid-depth on the midline; the torso's top above_carina above it.
  torso.frame.translation() = carina + (above_carina - 0.5 * torso.length) * z;
  if (table != nullptr) {
    table->frame = Iso3::Identity();
    table->frame.linear().col(0) = x;
    table->frame.linear().col(1) = -z;  // along the body (x × y = z up)
    table->frame.linear().col(2) = y;
    table->frame.translation() = torso.frame.translation() - 0.5 * torso.depth * y;
  }
}

Iso3 arm_base_beside(const TorsoModel& torso, const TableModel& table, int side, double lateral, double below_top,
                     const Vec3& at) {
  const Vec3 up = table.frame.linear().col(2);
  const Vec3 across = torso.frame.linear().col(0) * (side >= 0 ? 1.0 : -1.0);
  const Vec3 along = torso.frame.linear().col(2);
  Vec3 p = table.frame.translation() + lateral * across - below_top * up;
  p += (at - p).dot(along) * along;
  Iso3 b = Iso3::Identity();
  b.linear().col(2) = up;
  b.linear().col(0) = -across;  // facing the table
  b.linear().col(1) = up.cross(-across);
  b.translation() = p;
  return b;
}

void place_arms_for(PlatformModel& model, const Vec3& target) {
  if (!model.body || model.arms.empty() || !model.arms.front().other_side) return;
  const Iso3& torso = model.body->frame;
  const Vec3 x = torso.linear().col(0);
  const auto side_of = [&](const Vec3& p) { return (p - torso.translation()).dot(x) >= 0.0; };
  if (side_of(model.arms.front().base.translation()) == side_of(target)) return;
  for (ArmMount& m : model.arms) {
    if (m.other_side) std::swap(m.base, *m.other_side);
  }
}

Iso3 magnet_pose(const ArmModel& arm, const ArmMount& mount, const JointVector& q) {
  return flange_pose(arm, mount.base, q) * mount.tool.flange_to_magnet;
}

struct PlatformWorld::Impl {
  const PlatformModel& model;
  btDefaultCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher{&configuration};
  btDbvtBroadphase broadphase;
  btMultiBodyConstraintSolver solver;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;

  // Static colliders.
  std::unique_ptr<btConvexInternalShape> torso_shape;
  std::unique_ptr<btBoxShape> table_shape;
  btCollisionObject torso_object, table_object;

  struct Arm {
    std::unique_ptr<btMultiBody> body;
    std::array<std::unique_ptr<btCapsuleShapeZ>, kArmJoints + 1> capsules;  ///< [0] the base link
    std::array<Iso3, kArmJoints + 1> capsule_in_link;                       ///< capsule placement, link frame
    std::unique_ptr<btCylinderShapeZ> magnet;
    std::array<std::unique_ptr<btCompoundShape>, kArmJoints> compounds;  ///< the link colliders' shapes
    std::array<std::unique_ptr<btMultiBodyLinkCollider>, kArmJoints> colliders;
    std::array<Vec3, kArmJoints> com;  ///< Bullet's link frames sit at the centres of mass (with the magnet on 7)
    JointVector q = JointVector::Zero();
  };
  std::vector<Arm> arms;

  explicit Impl(const PlatformModel& m) : model(m) {
    world = std::make_unique<btMultiBodyDynamicsWorld>(&dispatcher, &broadphase, &solver, &configuration);
    world->setGravity(bt(model.gravity));
    if (model.body) {
      const TorsoModel& t = *model.body;
      torso_shape = std::make_unique<EllipticCylinderShape>(0.5 * t.breadth, 0.5 * t.depth, 0.5 * t.length);
      torso_object.setCollisionShape(torso_shape.get());
      torso_object.setWorldTransform(bt(t.frame));
      world->addCollisionObject(&torso_object);
    }
    if (model.table) {
      const TableModel& t = *model.table;
      table_shape = std::make_unique<btBoxShape>(btVector3(0.5 * t.width, 0.5 * t.length, 0.5 * t.thickness));
      table_shape->setMargin(kMargin);
      Iso3 centre = t.frame;
      centre.translation() -= 0.5 * t.thickness * t.frame.linear().col(2);
      table_object.setCollisionShape(table_shape.get());
      table_object.setWorldTransform(bt(centre));
      world->addCollisionObject(&table_object);
    }
    arms.resize(model.arms.size());
    for (std::size_t a = 0; a < arms.size(); ++a) build_arm(model.arms[a], arms[a]);
  }

  ~Impl() {
    for (Arm& a : arms) {
      for (auto& c : a.colliders) world->removeCollisionObject(c.get());
      world->removeMultiBody(a.body.get());
    }
    if (model.table) world->removeCollisionObject(&table_object);
    if (model.body) world->removeCollisionObject(&torso_object);
  }

  void build_arm(const ArmMount& mount, Arm& a) {
    const ArmModel& arm = model.arm;
    a.body = std::make_unique<btMultiBody>(kArmJoints, 0.0, btVector3(0, 0, 0), true, false);
    a.body->setBaseWorldTransform(bt(mount.base));
    Vec3 parent_com = Vec3::Zero();  // the fixed base's frame is the mount's
    for (int i = 0; i < kArmJoints; ++i) {
      const ArmLink& l = arm.links[static_cast<std::size_t>(i)];
      double mass = l.mass;
      Vec3 com = l.com;
      if (i == kArmJoints - 1 && mount.tool.mass > 0.0) {
        // The magnet rides on link 7: one body, its centre of mass the weighted mean.
        const Vec3 tool_com = arm.flange * mount.tool.com;
        com = (l.mass * l.com + mount.tool.mass * tool_com) / (l.mass + mount.tool.mass);
        mass += mount.tool.mass;
      }
      a.com[static_cast<std::size_t>(i)] = com;
      const Eigen::Quaterniond r(l.origin.linear().transpose());  // parent → this at q = 0
      a.body->setupRevolute(i, mass, bt(l.inertia), i - 1, btQuaternion(r.x(), r.y(), r.z(), r.w()), btVector3(0, 0, 1),
                            bt(Vec3(l.origin.translation() - parent_com)), bt(com), true);
      parent_com = com;
    }
    a.body->finalizeMultiDof();
    a.body->setLinearDamping(0.0);
    a.body->setAngularDamping(0.0);
    a.body->setHasSelfCollision(false);
    a.body->setMaxCoordinateVelocity(1e12);  // the default, 100 rad/s, would clip holding_torques' probe accelerations
    world->addMultiBody(a.body.get());
    // Colliders: a capsule per link (placed in the link frame, then moved to Bullet's centre-of-mass frame), the
    // magnet a cylinder on link 7.
    const auto capsule = [](const ArmLink& l) {
      return std::make_unique<btCapsuleShapeZ>(l.capsule_radius, (l.capsule_b - l.capsule_a).norm());
    };
    a.capsules[0] = capsule(arm.base);
    a.capsule_in_link[0] = capsule_placement(arm.base.capsule_a, arm.base.capsule_b);
    const double h = 0.5 * mount.magnet_length;
    a.magnet = std::make_unique<btCylinderShapeZ>(btVector3(mount.magnet_radius, mount.magnet_radius, h));
    a.magnet->setMargin(kMargin);
    for (int i = 0; i < kArmJoints; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const ArmLink& l = arm.links[k];
      a.capsules[k + 1] = capsule(l);
      a.capsule_in_link[k + 1] = capsule_placement(l.capsule_a, l.capsule_b);
      a.compounds[k] = std::make_unique<btCompoundShape>();
      Iso3 shift = Iso3::Identity();
      shift.translation() = -a.com[k];
      a.compounds[k]->addChildShape(bt(shift * a.capsule_in_link[k + 1]), a.capsules[k + 1].get());
      if (i == kArmJoints - 1) {
        a.compounds[k]->addChildShape(bt(shift * arm.flange * mount.tool.flange_to_magnet), a.magnet.get());
      }
      a.colliders[k] = std::make_unique<btMultiBodyLinkCollider>(a.body.get(), i);
      a.colliders[k]->setCollisionShape(a.compounds[k].get());
      world->addCollisionObject(a.colliders[k].get());
      a.body->getLink(i).m_collider = a.colliders[k].get();
    }
    set(a, mount.home);
  }

  void set(Arm& a, const JointVector& q) {
    a.q = q;
    for (int i = 0; i < kArmJoints; ++i) a.body->setJointPos(i, q[i]);
    btAlignedObjectArray<btQuaternion> world_to_local;
    btAlignedObjectArray<btVector3> local_origin;
    a.body->forwardKinematics(world_to_local, local_origin);
    a.body->updateCollisionObjectWorldTransforms(world_to_local, local_origin);
  }

  /// The arm's convex pieces in the world: the base capsule, the link capsules, the magnet.
  struct Piece {
    const btConvexShape* shape;
    btTransform transform;
    int index;  ///< 0 base, 1..7 links, 8 magnet
  };
  std::vector<Piece> pieces(std::size_t arm) const {
    const Arm& a = arms[arm];
    const ArmMount& mount = model.arms[arm];
    std::vector<Piece> out;
    out.push_back({a.capsules[0].get(), bt(Iso3(mount.base * a.capsule_in_link[0])), 0});
    for (int i = 0; i < kArmJoints; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const btCompoundShape& c = *a.compounds[k];
      const btTransform& w = a.colliders[k]->getWorldTransform();
      for (int s = 0; s < c.getNumChildShapes(); ++s) {
        const auto* shape = static_cast<const btConvexShape*>(c.getChildShape(s));
        out.push_back({shape, w * c.getChildTransform(s), shape == a.magnet.get() ? kArmJoints + 1 : i + 1});
      }
    }
    return out;
  }
};

PlatformWorld::PlatformWorld(const PlatformModel& model) : m(std::make_unique<Impl>(model)) {}
PlatformWorld::~PlatformWorld() = default;

void PlatformWorld::set_joints(int arm, const JointVector& q) {
  m->set(m->arms[static_cast<std::size_t>(arm)], q);
}

namespace {
const char* piece_name(int index) {
  static const char* kNames[] = {"base",   "link 1", "link 2", "link 3", "link 4",
                                 "link 5", "link 6", "link 7", "magnet"};
  return kNames[index];
}
}  // namespace

ArmCheck PlatformWorld::check(int arm) const {
  const auto a = static_cast<std::size_t>(arm);
  ArmCheck c;
  c.skin_clearance = std::numeric_limits<double>::infinity();
  c.nearest = std::numeric_limits<double>::infinity();
  // The nearest pair: this arm's piece, and the torso (−1), the table (−2) or the other arm's piece (its index);
  // named once at the end.
  int near_mine = 0, near_other = -1;
  const auto note = [&](double d, int mine, int other) {
    if (d < c.nearest) {
      c.nearest = d;
      near_mine = mine;
      near_other = other;
    }
  };
  const std::vector<Impl::Piece> mine = m->pieces(a);
  for (const Impl::Piece& p : mine) {
    if (m->model.body) {
      const double d = signed_distance(*p.shape, p.transform, *m->torso_shape, m->torso_object.getWorldTransform());
      if (p.index == kArmJoints + 1) c.skin_clearance = d;
      note(d, p.index, -1);
    }
    if (m->model.table && p.index > 0) {  // the base stands beside the table
      note(signed_distance(*p.shape, p.transform, *m->table_shape, m->table_object.getWorldTransform()), p.index, -2);
    }
  }
  for (std::size_t o = 0; o < m->arms.size(); ++o) {
    if (o == a) continue;
    const std::vector<Impl::Piece> theirs = m->pieces(o);
    for (const Impl::Piece& p : mine) {
      for (const Impl::Piece& q : theirs)
        note(signed_distance(*p.shape, p.transform, *q.shape, q.transform), p.index, q.index);
    }
  }
  if (std::isfinite(c.nearest)) {
    c.nearest_what = std::string(piece_name(near_mine)) +
                     (near_other == -1   ? " – torso"
                      : near_other == -2 ? " – table"
                                         : std::string(" – other arm's ") + piece_name(near_other));
  }
  c.collision = c.nearest < 0.0;
  return c;
}

double PlatformWorld::skin_distance(int arm, const Iso3& magnet_pose, bool depth) const {
  if (!m->model.body) return std::numeric_limits<double>::infinity();
  return signed_distance(*m->arms[static_cast<std::size_t>(arm)].magnet, bt(magnet_pose), *m->torso_shape,
                         m->torso_object.getWorldTransform(), depth);
}

double PlatformWorld::table_distance(int arm, const Iso3& magnet_pose) const {
  if (!m->model.table) return std::numeric_limits<double>::infinity();
  return signed_distance(*m->arms[static_cast<std::size_t>(arm)].magnet, bt(magnet_pose), *m->table_shape,
                         m->table_object.getWorldTransform(), false);
}

std::array<Iso3, kArmJoints> PlatformWorld::bullet_link_frames(int arm) const {
  const Impl::Arm& a = m->arms[static_cast<std::size_t>(arm)];
  std::array<Iso3, kArmJoints> f;
  for (int i = 0; i < kArmJoints; ++i) {
    const auto k = static_cast<std::size_t>(i);
    Iso3 shift = Iso3::Identity();
    shift.translation() = -a.com[k];
    f[k] = eig(a.colliders[k]->getWorldTransform()) * shift;
  }
  return f;
}

JointVector PlatformWorld::holding_torques(int arm, const Vec3& force, const Vec3& torque) {
  Impl::Arm& a = m->arms[static_cast<std::size_t>(arm)];
  btMultiBody& body = *a.body;
  const ArmMount& mount = m->model.arms[static_cast<std::size_t>(arm)];
  const Vec3 magnet_centre = magnet_pose(m->model.arm, mount, a.q).translation();
  btAlignedObjectArray<btScalar> scratch_r;
  btAlignedObjectArray<btVector3> scratch_v;
  btAlignedObjectArray<btMatrix3x3> scratch_m;
  // The accelerations at rest under joint torques tau, gravity and the wrench: the algorithm adds dt times them to
  // the (zero) velocities; Bullet clamps joint speeds (setMaxCoordinateVelocity, raised when the arm is built).
  const auto accelerations = [&](const JointVector& tau, bool loads) {
    body.clearForcesAndTorques();
    body.clearVelocities();
    for (int i = 0; i < kArmJoints; ++i) {
      if (loads) {
        body.addLinkForce(i, bt(Vec3(body.getLinkMass(i) * m->model.gravity)));
      }
      body.addJointTorque(i, tau[i]);
    }
    if (loads) {
      const Vec3 com7 = eig(a.colliders.back()->getWorldTransform().getOrigin());
      body.addLinkForce(kArmJoints - 1, bt(force));
      body.addLinkTorque(kArmJoints - 1, bt(Vec3(torque + (magnet_centre - com7).cross(force))));
    }
    constexpr double kDt = 1e-3;
    body.computeAccelerationsArticulatedBodyAlgorithmMultiDof(kDt, scratch_r, scratch_v, scratch_m, false, false,
                                                              false);
    JointVector acc;
    for (int i = 0; i < kArmJoints; ++i) acc[i] = body.getJointVel(i) / kDt;
    return acc;
  };
  const JointVector a0 = accelerations(JointVector::Zero(), true);
  Eigen::Matrix<double, kArmJoints, kArmJoints> inverse_mass;
  for (int i = 0; i < kArmJoints; ++i) inverse_mass.col(i) = accelerations(JointVector::Unit(i), false);
  body.clearForcesAndTorques();
  body.clearVelocities();
  return -inverse_mass.partialPivLu().solve(a0);
}

}  // namespace magvine::platform

namespace magvine::platform {

namespace {

Iso3 pose_of(const Vec3& position, const Vec3& axis) {
  Iso3 t = Iso3::Identity();
  t.linear() = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), axis.normalized()).toRotationMatrix();
  t.translation() = position;
  return t;
}

}  // namespace

PlatformRun::PlatformRun(const PlatformModel& model) : m_model(model), m_world(model), m_arms(model.arms.size()) {
  for (std::size_t a = 0; a < m_arms.size(); ++a) {
    m_arms[a].q = m_arms[a].goal = model.arms[a].home;
    m_arms[a].asked = platform::magnet_pose(model.arm, model.arms[a], model.arms[a].home).translation();
  }
}

int PlatformRun::arm_of_magnet(int magnet) const {
  for (std::size_t a = 0; a < m_model.arms.size(); ++a) {
    if (m_model.arms[a].magnet == magnet) return static_cast<int>(a);
  }
  return -1;
}

JointVector PlatformRun::holding_torques_at(int arm, const JointVector& q, const Vec3& force, const Vec3& torque) {
  m_world.set_joints(arm, q);
  const JointVector tau = m_world.holding_torques(arm, force, torque);
  m_world.set_joints(arm, m_arms[static_cast<std::size_t>(arm)].q);
  return tau;
}

std::vector<PlatformRun::Capsule> PlatformRun::link_capsules() const {
  std::vector<Capsule> out;
  const ArmModel& arm = m_model.arm;
  for (std::size_t a = 0; a < m_arms.size(); ++a) {
    const Iso3& base = m_model.arms[a].base;
    out.push_back({base * arm.base.capsule_a, base * arm.base.capsule_b, arm.base.capsule_radius});
    const std::array<Iso3, kArmJoints> frames = link_frames(arm, base, m_arms[a].q);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const ArmLink& l = arm.links[i];
      out.push_back({frames[i] * l.capsule_a, frames[i] * l.capsule_b, l.capsule_radius});
    }
  }
  return out;
}

Vec3 PlatformRun::arm_side(int arm) const {
  if (!m_model.body) return Vec3::Zero();
  const Vec3 x = m_model.body->frame.linear().col(0);
  const Vec3 d = m_model.arms[static_cast<std::size_t>(arm)].base.translation() - m_model.body->frame.translation();
  return d.dot(x) >= 0.0 ? x : Vec3(-x);
}

Iso3 PlatformRun::magnet_pose(int arm) const {
  const auto a = static_cast<std::size_t>(arm);
  return platform::magnet_pose(m_model.arm, m_model.arms[a], m_arms[a].q);
}

std::string PlatformRun::pose_problem(int arm, const JointVector& q) {
  m_world.set_joints(arm, q);
  const ArmCheck c = m_world.check(arm);
  if (c.collision) return "the arm would collide (" + c.nearest_what + ")";
  if (c.skin_clearance < m_model.clearance - 1e-9) return "the magnet would come within the clearance of the skin";
  if (m_pose_check) return m_pose_check(arm, q);
  return {};
}

std::string PlatformRun::way_problem(int arm, const std::vector<JointVector>& legs) {
  constexpr int kMaxWaySteps = 5000;
  const ArmState& s = m_arms[static_cast<std::size_t>(arm)];
  JointVector q = s.q, qd = s.qd;
  for (const JointVector& goal : legs) {
    for (int step = 0; step < kMaxWaySteps; ++step) {
      const bool there = track_joints(m_model.arm, goal, m_dt, q, qd);
      std::string why = pose_problem(arm, q);
      if (!why.empty()) return "on the way there: " + why;
      if (there) break;
    }
  }
  return {};
}

Placement PlatformRun::evaluate(int arm, const Vec3& position, const Vec3& axis, bool near_only, bool either_way) {
  if (either_way) {
    // A field whose use does not care for the axis's sign (a soft-magnetic fill's pull follows |B|): the magnet
    // turned round first (an axial mount then holds it from outside), then as asked.
    Placement p = evaluate(arm, position, -axis, near_only, false);
    if (p.feasible) return p;
    Placement q = evaluate(arm, position, axis, near_only, false);
    return q.feasible ? q : p;
  }
  constexpr double kNearJoints = 20.0 * kPi / 180.0;
  const auto a = static_cast<std::size_t>(arm);
  const ArmMount& mount = m_model.arms[a];
  IkOptions options;
  options.task = IkTask::kPositionAxis;
  options.restarts = 0;
  // Starts: where the arm is (the nearest solution: smooth motion, and no drift of the posture from one request to
  // the next); unless near_only, an elbow-up posture first, then its home and random joint vectors (seeded by the
  // request, so a run is deterministic).
  std::vector<JointVector> starts{m_arms[a].q};
  if (!near_only) {
    // Elbow up, the hand turned down towards the table (A2 40°, A4 −80°, A6 60°): the posture that reaches over a
    // patient beside the arm; first, so that a new posture is this branch when it can be.
    JointVector elbow_up;
    elbow_up << 0, 40, 0, -80, 0, 60, 0;
    starts.insert(starts.begin(), elbow_up * kPi / 180.0);
    starts.push_back(mount.home);
    std::mt19937_64 rng(static_cast<std::uint64_t>(std::abs(position.sum()) * 1e6) + a);
    constexpr int kRandomStarts = 6;
    for (int k = 0; k < kRandomStarts; ++k) starts.push_back(random_joints(m_model.arm, rng));
  }
  // The IK for a magnet pose from a start: converged joints or none.
  const auto solve = [&](const Vec3& p, const Vec3& ax, const JointVector& start) -> std::optional<JointVector> {
    const IkResult r = solve_ik(m_model.arm, mount.base, mount.tool.flange_to_magnet, pose_of(p, ax), start, options);
    return r.converged ? std::optional<JointVector>(r.q) : std::nullopt;
  };
  // Out from the torso's axis at p (or up, without a torso): where a magnet backs out to move round the patient.
  const auto outward = [&](const Vec3& p) -> Vec3 {
    if (!m_model.body) return -m_model.gravity.normalized();
    const Iso3& f = m_model.body->frame;
    Vec3 out = p - f.translation();
    out -= out.dot(f.linear().col(2)) * f.linear().col(2);
    return out.norm() > 1e-9 ? Vec3(out.normalized()) : Vec3(f.linear().col(1));
  };
  Placement best;
  best.position = position;
  best.axis = axis.normalized();
  best.why = "out of the arm's reach";
  for (const JointVector& start : starts) {
    const std::optional<JointVector> q = solve(position, axis, start);
    if (!q) continue;
    // Near: a small move of the joints (≤ 20° each from where it is), not a new posture reached by a long way round.
    if (near_only && (*q - m_arms[a].q).cwiseAbs().maxCoeff() > kNearJoints) {
      best.why = "only a new posture of the arm reaches it";
      continue;
    }
    best.q = *q;
    best.via.clear();
    best.why = pose_problem(arm, *q);
    if (best.why.empty() && m_arms[a].placed) {
      // The way there: the tracker's own motion from where the arm is (joints and speeds), step by step as advance()
      // will move it, every step checked as advance() checks it. Blocked, it tries backing the magnet out from the
      // torso by 8 or 16 cm, moving round there and coming in again.
      best.why = way_problem(arm, {*q});
      if (!best.why.empty() && !near_only) {
        const Vec3 here = magnet_pose(arm).translation();
        const Vec3 here_axis = magnet_pose(arm).linear().col(2);
        for (const double back : {0.08, 0.16}) {
          const std::optional<JointVector> v1 = solve(here + back * outward(here), here_axis, m_arms[a].q);
          const std::optional<JointVector> v2 = solve(position + back * outward(position), axis, *q);
          if (!v1 || !v2) continue;
          if (way_problem(arm, {*v1, *v2, *q}).empty()) {
            best.via = {*v1, *v2};
            best.why.clear();
            break;
          }
        }
      }
    }
    if (best.why.empty()) {
      best.feasible = true;
      break;
    }
  }
  m_world.set_joints(arm, m_arms[a].q);
  return best;
}

double PlatformRun::clear_distance(int arm, const Vec3& from, const Vec3& line, const Vec3& axis, double min_distance,
                                   double max_distance, double margin) const {
  const auto gap = [&](double d) {
    return m_world.skin_distance(arm, pose_of(from + d * line, axis), false) - m_model.clearance - margin;
  };  // (the magnet's clearance does not depend on its axis's sign)
  // A placement through the table is none.
  const auto under_table = [&](double d) { return m_world.table_distance(arm, pose_of(from + d * line, axis)) < 0.0; };
  if (gap(min_distance) >= 0.0)
    return under_table(min_distance) ? std::numeric_limits<double>::infinity() : min_distance;
  // Convex torso: along a line the gap rises once it starts to, so march out, then bisect to 0.1 mm.
  double lo = min_distance, hi = min_distance;
  do {
    lo = hi;
    hi += 0.01;
    if (hi > max_distance) return std::numeric_limits<double>::infinity();
  } while (gap(hi) < 0.0);
  while (hi - lo > 1e-4) {
    const double mid = 0.5 * (lo + hi);
    (gap(mid) >= 0.0 ? hi : lo) = mid;
  }
  return under_table(hi) ? std::numeric_limits<double>::infinity() : hi;
}

std::optional<Vec3> PlatformRun::shell_point(int arm, double angle, double level, const Vec3* axis,
                                             double standoff) const {
  if (!m_model.body) return std::nullopt;
  const Iso3& f = m_model.body->frame;
  const Vec3 from = f.translation() + shell_level(arm, level) * f.linear().col(2);
  const Vec3 out = shell_direction(angle);
  // 3 mm beyond the clearance, so that the way between two shell points (the chord, and the arm's joint motion
  // between them) keeps the clearance.
  constexpr double kShellMargin = 3e-3;
  const double d = clear_distance(arm, from, out, axis != nullptr ? *axis : out, 0.0, 2.0, kShellMargin);
  if (!std::isfinite(d)) return std::nullopt;
  return Vec3(from + (d + standoff) * out);
}

double PlatformRun::shell_level(int arm, double level) const {
  if (!m_model.body) return level;
  // Over the torso only (the neck and head above it, the legs below are not modelled): its length less the magnet's.
  const double reach = 0.5 * m_model.body->length - 0.5 * m_model.arms[static_cast<std::size_t>(arm)].magnet_length;
  return std::clamp(level, -reach, reach);
}

Vec3 PlatformRun::shell_direction(double angle) const {
  if (!m_model.body) return Vec3::Zero();
  const Iso3& f = m_model.body->frame;
  return std::cos(angle) * f.linear().col(0) + std::sin(angle) * f.linear().col(1);
}

std::pair<double, double> PlatformRun::shell_coordinates(const Vec3& x) const {
  if (!m_model.body) return {0.0, 0.0};
  const Iso3& f = m_model.body->frame;
  const Vec3 r = f.linear().transpose() * (x - f.translation());
  return {std::atan2(r.y(), r.x()), r.z()};
}

Placement PlatformRun::nearest_feasible(int arm, const Vec3& position, const Vec3& axis) {
  // Candidates in order of how far they move the magnet: out from the torso's axis to the clearance and beyond, and
  // round the request in 14 directions (the axes and the diagonals) at 1–16 cm.
  std::vector<std::pair<double, Vec3>> candidates;
  if (m_model.body) {
    const Iso3& f = m_model.body->frame;
    Vec3 out = position - f.translation();
    out -= out.dot(f.linear().col(2)) * f.linear().col(2);
    if (out.norm() > 1e-9) {
      out.normalize();
      const double d = clear_distance(arm, position, out, axis, 0.0, 0.5);
      if (std::isfinite(d)) {
        for (const double extra : {0.0, 0.005, 0.01, 0.02, 0.04}) candidates.emplace_back(d + extra, out);
      }
    }
  }
  std::vector<Vec3> directions;
  for (int i = 0; i < 3; ++i) {
    directions.push_back(Vec3::Unit(i));
    directions.push_back(-Vec3::Unit(i));
  }
  for (const double x : {-1.0, 1.0}) {
    for (const double y : {-1.0, 1.0}) {
      for (const double z : {-1.0, 1.0}) directions.push_back(Vec3(x, y, z).normalized());
    }
  }
  for (const double r : {0.01, 0.02, 0.04, 0.08, 0.16}) {
    for (const Vec3& d : directions) candidates.emplace_back(r, d);
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [r, d] : candidates) {
    Placement p = evaluate(arm, position + r * d, axis);
    if (p.feasible) return p;
  }
  Placement none;
  none.why = "no feasible pose within 16 cm";
  return none;
}

void PlatformRun::set_goal(int arm, const Placement& placement) {
  ArmState& s = m_arms[static_cast<std::size_t>(arm)];
  s.next = placement.via;
  s.next.push_back(placement.q);
  s.goal = s.next.front();
  s.next.erase(s.next.begin());
  s.asked = platform::magnet_pose(m_model.arm, m_model.arms[static_cast<std::size_t>(arm)], placement.q).translation();
}

namespace {
double leg_time(const ArmModel& arm, const JointVector& from, const JointVector& to) {
  return (to - from).cwiseAbs().cwiseQuotient(arm.qd_max).maxCoeff();
}
}  // namespace

double PlatformRun::remaining_time(int arm) const {
  const ArmState& s = m_arms[static_cast<std::size_t>(arm)];
  double t = leg_time(m_model.arm, s.q, s.goal);
  JointVector from = s.goal;
  for (const JointVector& v : s.next) {
    t += leg_time(m_model.arm, from, v);
    from = v;
  }
  return t;
}

void PlatformRun::jump_to_goal(int arm) {
  ArmState& s = m_arms[static_cast<std::size_t>(arm)];
  s.placed = true;
  if (!s.next.empty()) s.goal = s.next.back();
  s.next.clear();
  s.q = s.goal;
  s.qd.setZero();
  m_world.set_joints(arm, s.q);
}

Placement PlatformRun::request(int arm, const Vec3& position, const Vec3& axis, bool start) {
  const auto a = static_cast<std::size_t>(arm);
  m_arms[a].asked = position;
  // Near where the arm is first (a keyframed magnet moves a little each step), then any posture.
  Placement p = start ? evaluate(arm, position, axis) : evaluate(arm, position, axis, true);
  if (!p.feasible && !start) p = evaluate(arm, position, axis);
  if (!p.feasible) {
    const std::string why = p.why;
    p = nearest_feasible(arm, position, axis);
    p.why = p.feasible ? why + "; moved " +
                             std::to_string(static_cast<int>(std::lround((p.position - position).norm() * 1e3))) + " mm"
                       : why + "; " + p.why + ", the arm holds its goal";
  }
  if (p.feasible) {
    set_goal(arm, p);
    m_arms[a].asked = p.position;
    if (start) {
      m_arms[a].placed = true;
      m_arms[a].q = m_arms[a].goal = p.q;
      m_arms[a].next.clear();
      m_arms[a].qd.setZero();
      m_world.set_joints(arm, p.q);
    }
  }
  return p;
}

void PlatformRun::advance(double time, double dt, const std::function<std::vector<std::pair<Vec3, Vec3>>()>& wrenches) {
  if (dt > 0.0) m_dt = dt;
  bool violation = false;
  for (std::size_t a = 0; a < m_arms.size(); ++a) {
    ArmState& s = m_arms[a];
    const JointVector q0 = s.q, qd0 = s.qd;
    if (dt > 0.0 && track_joints(m_model.arm, s.goal, dt, s.q, s.qd) && !s.next.empty()) {
      s.goal = s.next.front();  // at a via point: on to the next
      s.next.erase(s.next.begin());
    }
    m_figures.path_length += (s.q - q0).cwiseAbs().sum();
    const ArmModel& arm = m_model.arm;
    for (int i = 0; i < kArmJoints; ++i) {
      const bool outside = s.q[i] < arm.q_min[i] - 1e-9 || s.q[i] > arm.q_max[i] + 1e-9;
      const bool fast = std::abs(s.qd[i]) > arm.qd_max[i] * (1.0 + 1e-9);
      const bool jerk = dt > 0.0 && std::abs(s.qd[i] - qd0[i]) > arm.qdd_max[i] * dt * (1.0 + 1e-9);
      violation = violation || outside || fast || jerk;
    }
    m_world.set_joints(static_cast<int>(a), s.q);
  }
  if (violation) ++m_figures.limit_violations;
  const std::vector<std::pair<Vec3, Vec3>> wrench = wrenches ? wrenches() : std::vector<std::pair<Vec3, Vec3>>{};
  bool collided = false;
  for (std::size_t a = 0; a < m_arms.size(); ++a) {
    const int arm = static_cast<int>(a);
    const ArmCheck c = m_world.check(arm);
    collided = collided || c.collision;
    m_figures.min_skin_clearance = std::min(m_figures.min_skin_clearance, c.skin_clearance);
    const auto& w = a < wrench.size() ? wrench[a] : std::pair<Vec3, Vec3>{Vec3::Zero(), Vec3::Zero()};
    const JointVector tau = m_world.holding_torques(arm, w.first, w.second);
    m_figures.max_torque_fraction =
        std::max(m_figures.max_torque_fraction, tau.cwiseAbs().cwiseQuotient(m_model.arm.tau_max).maxCoeff());
    const Vec3 reached = magnet_pose(arm).translation();
    m_figures.max_tracking_error = std::max(m_figures.max_tracking_error, (reached - m_arms[a].asked).norm());
    m_samples.push_back({time, arm, m_arms[a].q, tau, reached});
  }
  if (collided) ++m_figures.collisions;
}

}  // namespace magvine::platform
