// The force and torque between two EPMs (magnetics/interaction.hpp) against the dipole–dipole law far apart and
// against the independent volume form near, and Newton's third law between the pair.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "magvine/magnetics/interaction.hpp"

namespace magvine::magnetics {
namespace {

// The thesis's EPM: N52, Ø101.6 × 101.6 mm, J = 1.48 T (PHYSICS.md §1).
CylinderMagnet epm() {
  return CylinderMagnet(0.0508, 0.1016, Vec3(0, 0, 1.48));
}

double relative(const Vec3& a, const Vec3& b) {
  return (a - b).norm() / b.norm();
}

TEST(MagnetInteraction, TendsToTheDipoleLawFarApart) {
  // The cylinder's field departs from its dipole's by O((R/d)²) (L = D: no octupole cancellation), so the wrench
  // does too: the error must fall ~4× per doubling of the distance and be below 1e-4 at 8 m.
  const CylinderMagnet a = epm(), b = epm();
  const Vec3 dir = Vec3(1.0, 0.4, -0.3).normalized();
  const Pose pa = Pose::from_axis(Vec3::Zero(), Vec3(0.2, 0.1, 1.0));
  double previous = 0.0;
  for (const double d : {1.0, 2.0, 4.0, 8.0}) {
    const Pose pb = Pose::from_axis(d * dir, Vec3(1.0, -0.5, 0.3));
    const Wrench exact = magnet_magnet_wrench(a, pa, b, pb);
    const Vec3 ma = pa.rotation * a.dipole_moment(), mb = pb.rotation * b.dipole_moment();
    const Wrench dipole = magnetic_wrench(mb, dipole_field_gradient(ma, pb.position - pa.position));
    const double e_force = relative(exact.force, dipole.force);
    const double e_torque = relative(exact.torque, dipole.torque);
    std::printf("d %.0f m: force %.3g, torque %.3g\n", d, e_force, e_torque);
    if (previous > 0.0) {
      EXPECT_LT(e_force, previous / 3.0) << "d = " << d;
    }
    previous = e_force;
    if (d == 8.0) {
      EXPECT_LT(e_force, 1e-4);
      EXPECT_LT(e_torque, 1e-4);
    }
  }
}

TEST(MagnetInteraction, SurfaceAndVolumeFormsAgreeNear) {
  // Two independent integrals of one wrench (charges on the surface with the field; the gradient through the volume):
  // 1e-4 relative is the acceptance of issue 30; measured agreement is ~1e-9 at the fine rule.
  const CylinderMagnet a = epm();
  const CylinderMagnet b(0.0508, 0.1016, Vec3(0.6, 0.0, 1.3));  // tilted polarisation: side charges too
  const InteractionResolution fine{24, 24, 96};
  // b's axis is tilted 6.4° off a's: its rim dips 5.7 mm below the gap measured at its centre.
  for (const double gap : {0.015, 0.03, 0.1}) {
    const Pose pa = Pose::from_axis(Vec3::Zero(), Vec3(0, 0, 1));
    const Pose pb = Pose::from_axis(Vec3(0.03, 0.02, 0.1016 + gap), Vec3(0.1, -0.05, 1.0));
    const Wrench s = magnet_magnet_wrench(a, pa, b, pb, fine);
    const Wrench v = magnet_magnet_wrench_volume(a, pa, b, pb, fine);
    EXPECT_LT(relative(s.force, v.force), 1e-4) << "gap " << gap;
    EXPECT_LT(relative(s.torque, v.torque), 1e-4) << "gap " << gap;
    // The run-time default against the fine rule (the resolution's documented error) from a gap of R/5 on.
    if (gap - 0.0057 >= 0.0508 / 5) {
      const Wrench d = magnet_magnet_wrench(a, pa, b, pb);
      EXPECT_LT(relative(d.force, s.force), 1e-6) << "gap " << gap;
    }
  }
}

TEST(MagnetInteraction, ActionEqualsReaction) {
  // F_ab = −F_ba and the torques balance about any point: τ_a + τ_b + (c_a − c_b) × F_a = 0 (c_b the origin).
  const CylinderMagnet a = epm(), b = epm();
  const Pose pa = Pose::from_axis(Vec3(0.0, 0.0, 0.0), Vec3(1, 0, 0));
  const Pose pb = Pose::from_axis(Vec3(0.15, 0.12, 0.05), Vec3(0, 1, 1));
  const Wrench on_b = magnet_magnet_wrench(a, pa, b, pb);
  const Wrench on_a = magnet_magnet_wrench(b, pb, a, pa);
  EXPECT_LT((on_a.force + on_b.force).norm(), 1e-6 * on_b.force.norm());
  const Vec3 moment = on_a.torque + on_b.torque + (pa.position - pb.position).cross(on_a.force);
  EXPECT_LT(moment.norm(), 1e-6 * (on_b.torque.norm() + 0.2 * on_b.force.norm()));
}

}  // namespace
}  // namespace magvine::magnetics
