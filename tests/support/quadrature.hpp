#pragma once
// Independent numerical references for the cylinder fields: direct quadrature of the magnet's equivalent
// surface sources (no elliptic integrals, no shared code with src/magnetics).

#include <cmath>
#include <numbers>
#include <vector>

#include "magvine/core/eigen_types.hpp"

namespace magvine::test {

/// Gauss–Legendre nodes and weights on [-1, 1] (Newton iteration on P_n).
inline void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.assign(n, 0.0);
  w.assign(n, 0.0);
  for (int i = 0; i < n; ++i) {
    double t = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = t;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      const double dp = n * (t * p1 - p0) / (t * t - 1.0);
      const double dt = p1 / dp;
      t -= dt;
      if (std::abs(dt) < 1e-16) break;
    }
    double p0 = 1.0, p1 = t;
    for (int k = 2; k <= n; ++k) {
      const double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    const double dp = n * (t * p1 - p0) / (t * t - 1.0);
    x[i] = t;
    w[i] = 2.0 / ((1.0 - t * t) * dp * dp);
  }
}

/// B/J of a cylinder (radius R, half-length h, axis z, centred at 0) at p, by quadrature over the side wall:
///  axial J:      Biot–Savart of the surface current K = (J/μ0) φ̂;
///  transverse J (along x): Coulomb field of the surface charge σ = (J/μ0) cos φ, plus J inside.
/// Trapezoid rule in φ (periodic, spectrally accurate) and composite Gauss–Legendre in z.
/// Accurate to ~1e-10 relative for points more than ~0.2 R from the surface.
inline Vec3 cylinder_by_quadrature(double R, double h, const Vec3& p, bool axial, int n_phi = 720, int panels = 40,
                                   int gl = 16) {
  std::vector<double> gx, gw;
  gauss_legendre(gl, gx, gw);
  Vec3 sum = Vec3::Zero();
  const double dphi = 2.0 * std::numbers::pi / n_phi;
  const double panel = 2.0 * h / panels;
  for (int k = 0; k < n_phi; ++k) {
    const double phi = k * dphi;
    const double c = std::cos(phi), s = std::sin(phi);
    for (int pi = 0; pi < panels; ++pi) {
      const double z_mid = -h + (pi + 0.5) * panel;
      for (int g = 0; g < gl; ++g) {
        const double zq = z_mid + 0.5 * panel * gx[g];
        const double wq = 0.5 * panel * gw[g] * dphi * R;
        const Vec3 d = p - Vec3(R * c, R * s, zq);
        const double r3 = std::pow(d.squaredNorm(), 1.5);
        if (axial) {
          const Vec3 t(-s, c, 0.0);
          sum += wq * t.cross(d) / r3;
        } else {
          sum += wq * c * d / r3;
        }
      }
    }
  }
  Vec3 b = sum / (4.0 * std::numbers::pi);
  const double rho = std::hypot(p.x(), p.y());
  if (!axial && rho < R && std::abs(p.z()) < h) b.x() += 1.0;
  return b;
}

}  // namespace magvine::test
