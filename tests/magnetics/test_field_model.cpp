// Superposition, poses (translation and rotation) and the batch API of FieldModel.

#include "magvine/magnetics/field_model.hpp"

#include <gtest/gtest.h>

#include "magvine/magnetics/dipole.hpp"
#include "support/compare.hpp"

namespace magvine::magnetics {
namespace {

using test::close;
using test::flat;

TEST(FieldModel, SuperpositionOfAllSourceKinds) {
  const CylinderMagnet cyl(0.0508, 0.1016, Vec3(0, 0, 1.48));
  const Vec3 m(0, 0, 970.1);
  const Vec3 u(0, 0.01, 0);
  FieldModel model;
  model.add(cyl, Pose::from_axis(Vec3(0, 0, 0), Vec3(0, 0, 1)));
  model.add(DipoleSource{m}, Pose{Vec3(0, 0, 0.3), Mat3::Identity()});
  model.add(UniformSource{u}, Pose{});
  EXPECT_TRUE(model.has_gradient());
  const Vec3 x(0.05, -0.08, 0.15);
  const FieldSample s = field_gradient(model, model.rest_poses, x);
  const FieldSample c = cyl.field_gradient(model.rest_poses[0].to_local(x));
  const FieldSample d = dipole_field_gradient(m, x - Vec3(0, 0, 0.3));
  EXPECT_TRUE(close(s.b, Vec3(model.rest_poses[0].rotation * c.b + d.b + u), 1e-14));
  EXPECT_TRUE(close(flat(s.g), flat(c.g + d.g), 1e-14));
  EXPECT_TRUE(close(field(model, model.rest_poses, x), s.b, 1e-15));
}

TEST(FieldModel, UniformOnlyModelHasNoGradient) {
  FieldModel model;
  model.add(UniformSource{Vec3(0.01, 0, 0)}, Pose{});
  EXPECT_FALSE(model.has_gradient());
}

TEST(FieldModel, CurvatureOfPosedDipolesMatchesDifferencesOfTheGradient) {
  // Two posed dipoles and a uniform field: closed-form curvature (the uniform one adds none) against central
  // differences of Gᵀw; a cylinder has none in closed form.
  FieldModel model;
  model.add(DipoleSource{Vec3(0, 0, 970.1)}, Pose::from_axis(Vec3(0.02, -0.2, 0.01), Vec3(0.3, 1.0, 0.2)));
  model.add(DipoleSource{Vec3(50, 0, 0)}, Pose::from_axis(Vec3(-0.1, 0.05, 0.1), Vec3(1.0, 0.0, -0.4)));
  model.add(UniformSource{Vec3(0.01, 0, 0)}, Pose{});
  ASSERT_TRUE(model.has_analytic_curvature());
  const Vec3 x(0.03, 0.01, -0.02);
  const Vec3 w(0.4, -1.0, 0.3);
  Mat3 fd;
  const double step = 1e-6;
  for (int j = 0; j < 3; ++j) {
    const Vec3 e = step * Vec3::Unit(j);
    fd.col(j) = (field_gradient(model, model.rest_poses, x + e).g - field_gradient(model, model.rest_poses, x - e).g)
                    .transpose() *
                w / (2 * step);
  }
  EXPECT_TRUE(close(flat(field_curvature(model, model.rest_poses, x, w)), flat(fd), 1e-7));  // O(step²/d²), d ≥ 0.1 m
  model.add(CylinderMagnet(0.0508, 0.1016, Vec3(0, 0, 1.48)), Pose{});
  EXPECT_FALSE(model.has_analytic_curvature());
}

TEST(FieldModel, RotatedAxialMagnetMatchesOnAxisFormulaAlongItsAxis) {
  // An axial magnet whose axis points along world (1, 1, 0)/√2, centred at c: along that line the field is
  // the on-axis closed form, directed along the axis — an independent check of the pose transform.
  const double R = 0.02, L = 0.03, J = 1.2, h = 0.5 * L;
  const Vec3 c(0.1, -0.2, 0.05);
  const Vec3 axis = Vec3(1, 1, 0).normalized();
  FieldModel model;
  model.add(CylinderMagnet(R, L, Vec3(0, 0, J)), Pose::from_axis(c, axis));
  for (double t : {-0.1, -0.02, 0.0, 0.03, 0.2}) {
    const double bz = 0.5 * J * ((t + h) / std::hypot(t + h, R) - (t - h) / std::hypot(t - h, R));
    EXPECT_TRUE(close(field(model, model.rest_poses, c + t * axis), Vec3(bz * axis), 1e-12, 1e-18)) << t;
  }
}

TEST(FieldModel, PoseMovesTheFieldRigidly) {
  // Moving the magnet by (c, Q) and the observer with it leaves the field fixed in the magnet frame:
  // B'(c + Q p) = Q B(p), G'(c + Q p) = Q G(p) Qᵀ. Diametric magnet, so the rotation about its axis matters.
  FieldModel model;
  model.add(CylinderMagnet(0.01, 0.02, Vec3(1.3, 0, 0)), Pose{});
  const Mat3 q = Eigen::AngleAxisd(1.1, Vec3(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Pose moved{Vec3(0.3, 0.1, -0.2), q};
  const Vec3 p(0.013, 0.004, -0.021);
  const FieldSample a = field_gradient(model, model.rest_poses, p);
  const std::vector<Pose> poses{moved};
  const FieldSample b = field_gradient(model, poses, moved.position + q * p);
  EXPECT_TRUE(close(b.b, Vec3(q * a.b), 1e-13));
  EXPECT_TRUE(close(flat(b.g), flat(q * a.g * q.transpose()), 1e-12));
}

TEST(FieldModel, BatchEqualsPointwise) {
  FieldModel model;
  model.add(CylinderMagnet(0.02, 0.02, Vec3(0.5, 0.2, 1.0)), Pose::from_axis(Vec3(0, 0, -0.1), Vec3(0, 1, 1)));
  model.add(DipoleSource{Vec3(1, 2, 3)}, Pose{Vec3(0.2, 0, 0), Mat3::Identity()});
  std::vector<Vec3> pts;
  for (int i = 0; i < 50; ++i) pts.emplace_back(0.01 * i - 0.2, 0.003 * i, 0.1 - 0.004 * i);
  std::vector<FieldSample> out(pts.size());
  std::vector<Vec3> b(pts.size());
  field_gradient_batch(model, model.rest_poses, pts, out);
  field_batch(model, model.rest_poses, pts, b);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const FieldSample s = field_gradient(model, model.rest_poses, pts[i]);
    EXPECT_TRUE(close(out[i].b, s.b, 0.0, 0.0));
    EXPECT_TRUE(close(b[i], s.b, 1e-15));
  }
}

}  // namespace
}  // namespace magvine::magnetics
