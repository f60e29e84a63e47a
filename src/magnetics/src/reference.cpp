#include "magvine/magnetics/reference.hpp"

#include <cmath>
#include <vector>

#include "magvine/core/quadrature.hpp"
#include "magvine/core/units.hpp"

namespace magvine::magnetics {


Vec3 cylinder_field_quadrature(const CylinderMagnet& magnet, const Vec3& p, const QuadratureResolution& res) {
  std::vector<double> gx, gw;
  gauss_legendre(res.gauss_order, gx, gw);
  const double r = magnet.radius();
  const double h = 0.5 * magnet.length();
  const Vec3& j = magnet.polarisation();
  const double dphi = 2.0 * kPi / res.n_phi;
  const double panel = 2.0 * h / res.z_panels;
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < res.n_phi; ++k) {
    const double phi = k * dphi;
    const double c = std::cos(phi), s = std::sin(phi);
    const Vec3 tangent(-s, c, 0.0);
    const double sigma = j.x() * c + j.y() * s;  // J_⊥·n̂ on the side wall (end faces carry J_z·n̂ = ±J_z,
                                                 // represented by the current sheet instead)
    for (int pi = 0; pi < res.z_panels; ++pi) {
      const double z_mid = -h + (pi + 0.5) * panel;
      for (int g = 0; g < res.gauss_order; ++g) {
        const double zq = z_mid + 0.5 * panel * gx[static_cast<std::size_t>(g)];
        const double wq = 0.5 * panel * gw[static_cast<std::size_t>(g)] * dphi * r;
        const Vec3 d = p - Vec3(r * c, r * s, zq);
        const double inv_r3 = 1.0 / std::pow(d.squaredNorm(), 1.5);
        sum += (wq * inv_r3) * (j.z() * tangent.cross(d) + sigma * d);
      }
    }
  }
  Vec3 b = sum / (4.0 * kPi);
  if (std::hypot(p.x(), p.y()) < r && std::abs(p.z()) < h) b += Vec3(j.x(), j.y(), 0.0);
  return b;
}

}  // namespace magvine::magnetics
