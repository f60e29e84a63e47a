#include "magvine/platform/platform.hpp"

#include <btBulletDynamicsCommon.h>

#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpaPenetrationDepthSolver.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkPairDetector.h>
#include <BulletCollision/NarrowPhaseCollision/btPointCollector.h>
#include <BulletCollision/NarrowPhaseCollision/btVoronoiSimplexSolver.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>

#include <cmath>
#include <limits>

#include <Eigen/LU>

#include "magvine/core/units.hpp"

namespace magvine::platform {

namespace {

static_assert(sizeof(btScalar) == sizeof(double), "magvine links Bullet in double precision only");

btVector3 bt(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3 eig(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

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
/// the true one (cylinders and boxes subtract it; the hull's points are pulled in by it).
constexpr double kMargin = 5e-4;

/// Signed distance between two convex shapes (negative: penetration depth, by EPA).
double signed_distance(const btConvexShape& a, const btTransform& ta, const btConvexShape& b, const btTransform& tb) {
  btVoronoiSimplexSolver simplex;
  btGjkEpaPenetrationDepthSolver epa;
  btGjkPairDetector gjk(&a, &b, &simplex, &epa);
  btGjkPairDetector::ClosestPointInput in;
  in.m_transformA = ta;
  in.m_transformB = tb;
  btPointCollector out;
  gjk.getClosestPoints(in, out, nullptr);
  return out.m_hasResult ? out.m_distance : std::numeric_limits<double>::infinity();
}

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
  std::unique_ptr<btConvexHullShape> torso_shape;
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
      torso_shape = std::make_unique<btConvexHullShape>();
      constexpr int kRound = 96;
      for (int i = 0; i < kRound; ++i) {
        const double phi = 2.0 * kPi * i / kRound;
        for (const double z : {-0.5 * t.length + kMargin, 0.5 * t.length - kMargin}) {
          torso_shape->addPoint(btVector3((0.5 * t.breadth - kMargin) * std::cos(phi),
                                          (0.5 * t.depth - kMargin) * std::sin(phi), z),
                                false);
        }
      }
      torso_shape->recalcLocalAabb();
      torso_shape->setMargin(kMargin);
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
      a.body->setupRevolute(i, mass, bt(l.inertia), i - 1, btQuaternion(r.x(), r.y(), r.z(), r.w()),
                            btVector3(0, 0, 1), bt(Vec3(l.origin.translation() - parent_com)), bt(com), true);
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

void PlatformWorld::set_joints(int arm, const JointVector& q) { m->set(m->arms[static_cast<std::size_t>(arm)], q); }

namespace {
const char* piece_name(int index) {
  static const char* kNames[] = {"base", "link 1", "link 2", "link 3", "link 4", "link 5", "link 6", "link 7",
                                 "magnet"};
  return kNames[index];
}
}  // namespace

ArmCheck PlatformWorld::check(int arm) const {
  const auto a = static_cast<std::size_t>(arm);
  ArmCheck c;
  c.skin_clearance = std::numeric_limits<double>::infinity();
  c.nearest = std::numeric_limits<double>::infinity();
  const auto note = [&](double d, const std::string& what) {
    if (d < c.nearest) {
      c.nearest = d;
      c.nearest_what = what;
    }
  };
  const std::vector<Impl::Piece> mine = m->pieces(a);
  for (const Impl::Piece& p : mine) {
    if (m->model.body) {
      const double d = signed_distance(*p.shape, p.transform, *m->torso_shape, m->torso_object.getWorldTransform());
      if (p.index == kArmJoints + 1) c.skin_clearance = d;
      note(d, std::string(piece_name(p.index)) + " – torso");
    }
    if (m->model.table && p.index > 0) {  // the base stands beside the table
      note(signed_distance(*p.shape, p.transform, *m->table_shape, m->table_object.getWorldTransform()),
           std::string(piece_name(p.index)) + " – table");
    }
  }
  for (std::size_t o = 0; o < m->arms.size(); ++o) {
    if (o == a) continue;
    for (const Impl::Piece& p : mine) {
      for (const Impl::Piece& q : m->pieces(o)) {
        note(signed_distance(*p.shape, p.transform, *q.shape, q.transform),
             std::string(piece_name(p.index)) + " – other arm's " + piece_name(q.index));
      }
    }
  }
  c.collision = c.nearest < 0.0;
  return c;
}

double PlatformWorld::skin_distance(int arm, const Iso3& magnet_pose) const {
  if (!m->model.body) return std::numeric_limits<double>::infinity();
  return signed_distance(*m->arms[static_cast<std::size_t>(arm)].magnet, bt(magnet_pose), *m->torso_shape,
                         m->torso_object.getWorldTransform());
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
