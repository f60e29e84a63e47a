#include "magvine/magnetics/cylinder.hpp"

#include <cmath>

#include "magvine/core/check.hpp"
#include "magvine/core/elliptic.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "magvine/magnetics/magnetisation.hpp"

namespace magvine::magnetics {

namespace {

// Points closer than this (in units of R) to a rim edge or to an end-face loop wire count as on it.
constexpr double kEdgeTol = 1e-14;

// Everything below works in coordinates scaled by R (r = ρ/R, z = z/R, z0 = h/R) and returns B per unit J.
// None of it may be called on a rim edge (r = 1, |z| = z0), where cel's modulus, the loop's q and a± vanish:
// CylinderMagnet::evaluate returns before that.

struct AxialField {
  double br = 0.0;  // B_ρ / J_z
  double bz = 0.0;  // B_z / J_z
};

// Axially magnetised cylinder, Derby & Olbert 2010 via cel (fields.md §3). Valid inside and outside.
AxialField axial_field(double r, double z, double z0) {
  const double zp = z + z0;
  const double zm = z - z0;
  const double sp = std::sqrt(zp * zp + (1.0 + r) * (1.0 + r));
  const double sm = std::sqrt(zm * zm + (1.0 + r) * (1.0 + r));
  const double kp = std::sqrt(zp * zp + (1.0 - r) * (1.0 - r)) / sp;
  const double km = std::sqrt(zm * zm + (1.0 - r) * (1.0 - r)) / sm;
  const double gamma = (1.0 - r) / (1.0 + r);
  const double g2 = gamma * gamma;
  AxialField f;
  f.br = (cel(kp, 1.0, 1.0, -1.0) / sp - cel(km, 1.0, 1.0, -1.0) / sm) / kPi;
  f.bz = (zp * cel(kp, g2, 1.0, gamma) / sp - zm * cel(km, g2, 1.0, gamma) / sm) / (kPi * (1.0 + r));
  return f;
}

struct LoopField {
  double br = 0.0;  // B_ρ · R/(μ0 I)
  double bz = 0.0;  // B_z · R/(μ0 I)
};

// Circular current loop of unit radius in the plane ζ = 0, current right-handed about +z (Ortner et al. 2023).
// The first Bulirsch step is done analytically so that nothing cancels near the axis (fields.md §3).
LoopField loop_field(double r, double zeta) {
  const double x0 = zeta * zeta + (r + 1.0) * (r + 1.0);
  const double k2 = 4.0 * r / x0;
  const double q2 = (zeta * zeta + (r - 1.0) * (r - 1.0)) / x0;
  const double q = std::sqrt(q2);
  const double p = 1.0 + q;
  const double b1 = 2.0 * std::sqrt(q);
  const double pf = 1.0 / (4.0 * kPi * std::sqrt(x0) * q2);
  // cel(q, 1, 1, −q²) and cel(q, 1, k² − 4/x0, −q²(k² + 4/x0)) after their first iteration.
  const double cel_r = cel_iterate(p, b1, p, k2, 2.0 * k2 * q / p);
  const double cel_z = cel_iterate(p, b1, p, k2 * k2 - (1.0 + q2) * 4.0 / x0, 2.0 * q * (k2 * k2 / p - 4.0 * p / x0));
  return {pf * (4.0 * zeta / x0) * cel_r, -pf * cel_z};
}

// Derivatives of the axial field per unit J, in scaled coordinates (multiply by J/R for T/m):
// e = ∂B_ρ/∂z, g = ∂B_z/∂z from the end-face loops; b = B_ρ/ρ; a = ∂B_ρ/∂ρ = −b − g (div B = 0);
// ∂B_z/∂ρ = e (curl B = 0).
struct AxialDerivatives {
  double a, b, e, g;
};

AxialDerivatives axial_derivatives(double r, double z, double z0, double br) {
  const LoopField lp = loop_field(r, z + z0);
  const LoopField lm = loop_field(r, z - z0);
  AxialDerivatives d{};
  d.e = lp.br - lm.br;
  d.g = lp.bz - lm.bz;
  d.b = r < CylinderMagnet::kAxisLimit ? -0.5 * d.g : br / r;
  d.a = -d.b - d.g;
  return d;
}

// Transverse (diametric) magnetisation along +x, per unit J, in the cylindrical frame of the observer:
// H_ρ = fr cos φ, H_φ = fphi sin φ, H_z = fz cos φ (μ0 H / J), and s = (fr + fphi)/ρ for the gradient.
struct DiametricField {
  double fr = 0.0, fphi = 0.0, fz = 0.0, s = 0.0;
};

DiametricField diametric_series(double r, double z, double z0) {
  // Taylor expansion in r (Magpylib, fields.md §4), accurate to O(r⁶).
  const double zp = z + z0;
  const double zm = z - z0;
  const double zpp = zp * zp + 1.0;
  const double zmp = zm * zm + 1.0;
  const double sp = std::sqrt(zpp);
  const double sm = std::sqrt(zmp);
  const double fp = zp / sp;
  const double fm = zm / sm;
  const double r2 = r * r;
  const double zpp2 = zpp * zpp;
  const double zmp2 = zmp * zmp;
  const double t1 = fp - fm;
  const double t2 = (fp / zpp2 - fm / zmp2) / 8.0;                                              // T2 / r²
  const double t3 = ((3.0 - 4.0 * zp * zp) * fp / (zpp2 * zpp2) - (3.0 - 4.0 * zm * zm) * fm / (zmp2 * zmp2)) / 64.0;  // T3 / r⁴
  DiametricField d;
  d.fr = -(t1 + 9.0 * t2 * r2 + 25.0 * t3 * r2 * r2) / 4.0;
  d.fphi = (t1 + 3.0 * t2 * r2 + 5.0 * t3 * r2 * r2) / 4.0;
  const double zp2 = zp * zp;
  const double zm2 = zm * zm;
  const double c1 = 1.0 / (zpp * sp) - 1.0 / (zmp * sm);
  const double c3 = (1.0 - 4.0 * zp2) / (zpp * zpp2 * sp) - (1.0 - 4.0 * zm2) / (zmp * zmp2 * sm);
  const double c5 = (1.0 - 12.0 * zp2 + 8.0 * zp2 * zp2) / (zpp * zpp2 * zpp2 * sp) -
                    (1.0 - 12.0 * zm2 + 8.0 * zm2 * zm2) / (zmp * zmp2 * zmp2 * sm);
  d.fz = -0.25 * r * (c1 + 0.375 * r2 * c3 + (15.0 / 64.0) * r2 * r2 * c5);
  d.s = -(3.0 * t2 * r + 10.0 * t3 * r2 * r) / 2.0;
  return d;
}

DiametricField diametric_general(double r, double z, double z0) {
  // Caciagli et al. 2018 in Magpylib's form (fields.md §4); valid for r ≥ kSeriesRadius.
  const double zp = z + z0;
  const double zm = z - z0;
  const double rp = r + 1.0;
  const double rm = r - 1.0;
  const double ap2 = zp * zp + rm * rm;
  const double am2 = zm * zm + rm * rm;
  const double ap = std::sqrt(ap2);
  const double am = std::sqrt(am2);
  const double mp = -4.0 * r / ap2;
  const double mm = -4.0 * r / am2;
  const double ep = ellip_e(mp), em = ellip_e(mm);
  const double kp = ellip_k(mp), km = ellip_k(mm);
  // On ρ = R exactly n = −∞: Π → 0 and the Π/(r−1) term is set to 0, which gives the exact value beyond the
  // end faces and the mean of both sides on the side wall (fields.md §4).
  double pip = 0.0, pim = 0.0, inv_rm = 0.0;
  if (std::abs(rm) > 1e-15) {
    const double n = -4.0 * r / (rm * rm);
    pip = ellip_pi(n, mp);
    pim = ellip_pi(n, mm);
    inv_rm = 1.0 / rm;
  }
  const double zam = zm / am;
  const double zap = zp / ap;
  const double r2 = r * r;
  const double br = -zm * am * em + zp * ap * ep + zam * (2.0 + zm * zm) * km - zap * (2.0 + zp * zp) * kp +
                    (zam * pim - zap * pip) * rp * (r2 + 1.0) * inv_rm;
  const double bphi = zm * am * em - zp * ap * ep - zam * (2.0 + zm * zm + 2.0 * r2) * km +
                      zap * (2.0 + zp * zp + 2.0 * r2) * kp + zam * rp * rp * pim - zap * rp * rp * pip;
  const double bz = am * em - ap * ep - (1.0 + zm * zm + r2) / am * km + (1.0 + zp * zp + r2) / ap * kp;
  DiametricField d;
  d.fr = -br / (4.0 * kPi * r2);
  d.fphi = bphi / (4.0 * kPi * r2);
  d.fz = -bz / (2.0 * kPi * r);
  d.s = (d.fr + d.fphi) / r;
  return d;
}

}  // namespace

CylinderMagnet::CylinderMagnet(double radius, double length, const Vec3& polarisation)
    : m_radius(radius), m_half_length(0.5 * length), m_j(polarisation) {
  MAGVINE_ASSERT(radius > 0.0 && length > 0.0 && polarisation.allFinite());
  m_j_axial = polarisation.z();
  m_j_transverse = std::hypot(polarisation.x(), polarisation.y());
  m_cos_t = m_j_transverse > 0.0 ? polarisation.x() / m_j_transverse : 1.0;
  m_sin_t = m_j_transverse > 0.0 ? polarisation.y() / m_j_transverse : 0.0;
  const double far = kFarFieldDiameters * 2.0 * std::max(radius, m_half_length);
  m_far_radius2 = far * far;
  m_dipole = hard_magnetic_moment<3>(m_j, volume());  // J·V/μ0
}

double CylinderMagnet::volume() const { return kPi * m_radius * m_radius * 2.0 * m_half_length; }

Vec3 CylinderMagnet::field(const Vec3& p) const { return evaluate<false>(p).b; }

FieldSample CylinderMagnet::field_gradient(const Vec3& p) const { return evaluate<true>(p); }

template <bool kWithGradient>
FieldSample CylinderMagnet::evaluate(const Vec3& p) const {
  if (p.squaredNorm() > m_far_radius2) {
    if constexpr (kWithGradient) return dipole_field_gradient(dipole_moment(), p);
    FieldSample out;
    out.b = dipole_field(dipole_moment(), p);
    return out;
  }
  const double inv_r = 1.0 / m_radius;
  const double x = p.x() * inv_r;
  const double y = p.y() * inv_r;
  const double z = p.z() * inv_r;
  const double z0 = m_half_length * inv_r;
  const double rho = std::sqrt(x * x + y * y);
  // Rim edge: the field diverges logarithmically; report zero (the only guard the formulas below need).
  if (std::abs(rho - 1.0) < kEdgeTol && std::abs(std::abs(z) - z0) < kEdgeTol) return {};
  const double c = rho > 0.0 ? x / rho : 1.0;  // φ = atan2(0, 0) = 0 on the axis
  const double s = rho > 0.0 ? y / rho : 0.0;

  FieldSample out;
  const bool need_axial = m_j_axial != 0.0 || (kWithGradient && m_j_transverse != 0.0);
  AxialField ax;
  AxialDerivatives d{};
  if (need_axial) {
    ax = axial_field(rho, z, z0);
    if constexpr (kWithGradient) d = axial_derivatives(rho, z, z0, ax.br);
  }

  if (m_j_axial != 0.0) {
    out.b += m_j_axial * Vec3(ax.br * c, ax.br * s, ax.bz);
    if constexpr (kWithGradient) {
      Mat3 g;
      g << d.a * c * c + d.b * s * s, (d.a - d.b) * c * s, d.e * c,  //
          (d.a - d.b) * c * s, d.a * s * s + d.b * c * c, d.e * s,    //
          d.e * c, d.e * s, d.g;
      out.g += (m_j_axial * inv_r) * g;
    }
  }

  if (m_j_transverse != 0.0) {
    // Work in the frame rotated by θ about z in which the transverse polarisation points along +x.
    const double cp = c * m_cos_t + s * m_sin_t;
    const double sp = s * m_cos_t - c * m_sin_t;
    const DiametricField df = rho < kSeriesRadius ? diametric_series(rho, z, z0) : diametric_general(rho, z, z0);
    const double h_r = df.fr * cp;
    const double h_phi = df.fphi * sp;
    Vec3 bp(h_r * cp - h_phi * sp, h_r * sp + h_phi * cp, df.fz * cp);
    // B = μ0(H + M): add J inside the material, half of it on the surface itself.
    if (rho <= 1.0 && std::abs(z) <= z0) bp.x() += (rho < 1.0 && std::abs(z) < z0) ? 1.0 : 0.5;
    Mat3 rz;
    rz << m_cos_t, -m_sin_t, 0.0, m_sin_t, m_cos_t, 0.0, 0.0, 0.0, 1.0;
    out.b += m_j_transverse * (rz * bp);
    if constexpr (kWithGradient) {
      // ∂_z B for transverse J along x equals ∂_x B for the same J along z: column x of the axial gradient.
      const double dzx = d.a * cp * cp + d.b * sp * sp;
      const double dzy = (d.a - d.b) * cp * sp;
      const double dz_hr = cp * dzx + sp * dzy;
      const double dz_hphi = -sp * dzx + cp * dzy;
      const double dz_hz = d.e * cp;
      Mat3 gcyl;  // rows: component (ρ, φ, z); columns: derivative direction (ρ, φ, z)
      gcyl << -cp * df.s - dz_hz, -sp * df.s, dz_hr,  //
          -sp * df.s, cp * df.s, dz_hphi,              //
          dz_hr, dz_hphi, dz_hz;
      Mat3 rc;
      rc << cp, -sp, 0.0, sp, cp, 0.0, 0.0, 0.0, 1.0;
      const Mat3 r_all = rz * rc;
      out.g += (m_j_transverse * inv_r) * (r_all * gcyl * r_all.transpose());
    }
  }
  return out;
}

}  // namespace magvine::magnetics
