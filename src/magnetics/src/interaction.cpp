#include "magvine/magnetics/interaction.hpp"

#include <cmath>
#include <vector>

#include "magvine/core/quadrature.hpp"
#include "magvine/core/units.hpp"

namespace magvine::magnetics {

namespace {

/// The source's field at world points: B, and G when asked.
struct PosedSource {
  const CylinderMagnet& magnet;
  const Pose& pose;
  Vec3 field(const Vec3& x) const { return pose.rotation * magnet.field(pose.to_local(x)); }
  FieldSample field_gradient(const Vec3& x) const {
    const FieldSample local = magnet.field_gradient(pose.to_local(x));
    const Mat3& r = pose.rotation;
    return {r * local.b, r * local.g * r.transpose()};
  }
};

/// Quadrature nodes over the target's volume in its local frame: (point, weight) for every node, weights summing to
/// the volume. Gauss–Legendre in r (weight r dr) and z, trapezoid in φ.
template <class Visit>
void over_volume(const CylinderMagnet& target, const InteractionResolution& res, const Visit& visit) {
  std::vector<double> rx, rw, zx, zw;
  gauss_legendre(res.radial, rx, rw);
  gauss_legendre(res.axial, zx, zw);
  const double radius = target.radius();
  const double h = 0.5 * target.length();
  const double dphi = 2.0 * kPi / res.angular;
  for (std::size_t i = 0; i < rx.size(); ++i) {
    const double r = 0.5 * radius * (1.0 + rx[i]);
    const double wr = 0.5 * radius * rw[i] * r;
    for (std::size_t k = 0; k < zx.size(); ++k) {
      const double z = h * zx[k];
      const double wz = h * zw[k];
      for (int j = 0; j < res.angular; ++j) {
        const double phi = dphi * (j + 0.5);
        visit(Vec3(r * std::cos(phi), r * std::sin(phi), z), wr * wz * dphi);
      }
    }
  }
}

}  // namespace

Wrench magnet_magnet_wrench(const CylinderMagnet& source, const Pose& source_pose, const CylinderMagnet& target,
                            const Pose& target_pose, const InteractionResolution& res) {
  const PosedSource b{source, source_pose};
  const Mat3& rot = target_pose.rotation;
  const Vec3& c = target_pose.position;
  const Vec3 m_local = target.polarisation() / kMu0;  // M [A/m], target frame
  const double radius = target.radius();
  const double h = 0.5 * target.length();
  const double dphi = 2.0 * kPi / res.angular;
  std::vector<double> rx, rw, zx, zw;
  gauss_legendre(res.radial, rx, rw);
  gauss_legendre(res.axial, zx, zw);
  Wrench w;  // the charges' torques include the couple on the moment: ∮ σ x dA = ∫ M dV
  // Charge σ = M·n̂ at local point p with weight dA: F += σ B dA, τ += σ (x − c) × B dA.
  const auto charge = [&](const Vec3& p, double sigma_da) {
    const Vec3 arm = rot * p;
    const Vec3 f = sigma_da * b.field(c + arm);
    w.force += f;
    w.torque += arm.cross(f);
  };
  // End faces z = ±h: σ = ±M_z, dA = r dr dφ.
  if (m_local.z() != 0.0) {
    for (std::size_t i = 0; i < rx.size(); ++i) {
      const double r = 0.5 * radius * (1.0 + rx[i]);
      const double da = 0.5 * radius * rw[i] * r * dphi;
      for (int j = 0; j < res.angular; ++j) {
        const double phi = dphi * (j + 0.5);
        const double x = r * std::cos(phi), y = r * std::sin(phi);
        charge(Vec3(x, y, h), m_local.z() * da);
        charge(Vec3(x, y, -h), -m_local.z() * da);
      }
    }
  }
  // Side wall: σ = M_x cos φ + M_y sin φ, dA = R dφ dz.
  if (m_local.x() != 0.0 || m_local.y() != 0.0) {
    for (std::size_t k = 0; k < zx.size(); ++k) {
      const double z = h * zx[k];
      const double da = radius * dphi * h * zw[k];
      for (int j = 0; j < res.angular; ++j) {
        const double phi = dphi * (j + 0.5);
        const double cs = std::cos(phi), sn = std::sin(phi);
        charge(Vec3(radius * cs, radius * sn, z), (m_local.x() * cs + m_local.y() * sn) * da);
      }
    }
  }
  return w;
}

Wrench magnet_magnet_wrench_volume(const CylinderMagnet& source, const Pose& source_pose, const CylinderMagnet& target,
                                   const Pose& target_pose, const InteractionResolution& res) {
  const PosedSource b{source, source_pose};
  const Vec3 m = target_pose.rotation * target.polarisation() / kMu0;
  Wrench w;
  over_volume(target, res, [&](const Vec3& p, double dv) {
    const Vec3 arm = target_pose.rotation * p;
    const FieldSample f = b.field_gradient(target_pose.position + arm);
    const Wrench local = magnetic_wrench(m * dv, f);  // F = Gᵀ(M dV), τ = (M dV) × B
    w.force += local.force;
    w.torque += arm.cross(local.force) + local.torque;
  });
  return w;
}

}  // namespace magvine::magnetics
