// The collision library must be Bullet's double-precision build (DESIGN.md): btScalar is double, and the
// float64 libraries we link agree with the headers (a mismatch corrupts memory silently, so exercise them).

#include <btBulletCollisionCommon.h>
#include <gtest/gtest.h>

#include <cmath>

TEST(BulletPrecision, ScalarIsDouble) { EXPECT_EQ(sizeof(btScalar), 8u); }

TEST(BulletPrecision, RayHitsSphereAtDoublePrecisionDistance) {
  // A sphere of radius r at the origin, a ray from x = -1 along +x: first hit at x = -r exactly.
  // 1e-12 would be lost in single precision (eps 1.2e-7): the library itself must compute in double.
  const double r = 0.1234567890123;
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btCollisionWorld world(&dispatcher, &broadphase, &config);
  btSphereShape sphere(r);
  btCollisionObject object;
  object.setCollisionShape(&sphere);
  world.addCollisionObject(&object);
  world.updateAabbs();

  const btVector3 from(-1.0, 0.0, 0.0), to(1.0, 0.0, 0.0);
  btCollisionWorld::ClosestRayResultCallback hit(from, to);
  world.rayTest(from, to, hit);
  ASSERT_TRUE(hit.hasHit());
  constexpr double kTol = 1e-12;  // double-precision ray/sphere intersection, distance O(1)
  EXPECT_NEAR(hit.m_hitPointWorld.x(), -r, kTol);
  EXPECT_NEAR(hit.m_hitNormalWorld.x(), -1.0, kTol);
  world.removeCollisionObject(&object);
}
