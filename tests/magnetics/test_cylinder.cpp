// Exact cylinder field and gradient against independent references: on-axis closed forms, direct quadrature
// of the equivalent surface current/charge, finite differences, the point dipole in the far field, and the
// physics invariants (symmetry, continuity, curl B = 0, div B = 0).

#include "magvine/magnetics/cylinder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/dipole.hpp"
#include "support/compare.hpp"
#include "magvine/magnetics/reference.hpp"

namespace magvine::magnetics {
namespace {

using test::close;
using test::flat;

constexpr double kR = 0.0508;   // the thesis EPM: Ø101.6 × 101.6 mm
constexpr double kL = 0.1016;
constexpr double kJ = 1.48;

// Closed forms in double precision agree with quadrature/closed forms to ~1e-13 (fields.md §7); the
// quadrature reference (magnetics/reference.hpp, no shared code) is good to ~1e-10 at ≥ 0.2 R from the surface.
constexpr double kClosedFormTol = 1e-12;
constexpr double kQuadratureTol = 1e-8;
// Central differences with Richardson extrapolation, step 3e-3 R: truncation O(h⁴) ≈ 1e-10 and the noise of the
// closed forms (~2e-12 J near the series switch) divided by the step, ≈ 1e-9 J/R.
constexpr double kFdTol = 2e-7;
constexpr double kFdStep = 3e-3;  // in units of R

Vec3 on_axis_axial(double R, double h, double J, double z) {
  return Vec3(0, 0, 0.5 * J * ((z + h) / std::hypot(z + h, R) - (z - h) / std::hypot(z - h, R)));
}

Mat3 fd_gradient(const CylinderMagnet& c, const Vec3& p, double step) {
  Mat3 g;
  for (int j = 0; j < 3; ++j) {
    const Vec3 e = Vec3::Unit(j);
    const Vec3 d1 = (c.field(p + step * e) - c.field(p - step * e)) / (2 * step);
    const Vec3 d2 = (c.field(p + 2 * step * e) - c.field(p - 2 * step * e)) / (4 * step);
    g.col(j) = (4.0 * d1 - d2) / 3.0;  // Richardson: cancels the h² term
  }
  return g;
}

TEST(Cylinder, ThesisEpmDipoleMoment) {
  // Thesis 5.6.1: m = J V/μ0 = 970.1 A·m² for N52, Ø101.6 × 101.6 mm, J = 1.48 T.
  const CylinderMagnet epm(kR, kL, Vec3(0, 0, kJ));
  EXPECT_NEAR(epm.dipole_moment().z(), 970.1, 0.05);  // the thesis prints 4 digits
}

TEST(Cylinder, AxialOnAxisClosedForm) {
  const CylinderMagnet c(kR, kL, Vec3(0, 0, kJ));
  for (double z : {-0.5, -0.2, -0.06, -0.0508, -0.03, 0.0, 0.01, 0.0508, 0.0600, 0.1, 0.16, 0.3, 1.0}) {
    EXPECT_TRUE(close(c.field(Vec3(0, 0, z)), on_axis_axial(kR, 0.5 * kL, kJ, z), kClosedFormTol, 1e-18)) << "z=" << z;
  }
  // Centre: B_z = J h / sqrt(h² + R²).
  const double h = 0.5 * kL;
  EXPECT_NEAR(c.field(Vec3::Zero()).z(), kJ * h / std::hypot(h, kR), 1e-15);
}

TEST(Cylinder, DiametricOnAxisClosedForm) {
  // On the axis the transverse field is H = −(f+ − f−)/4 · M̂ with f± = z±/sqrt(z±² + R²) (scaled), plus J inside.
  const double R = 0.01, L = 0.03, h = 0.5 * L;
  const CylinderMagnet c(R, L, Vec3(kJ, 0, 0));
  for (double z : {-0.2, -0.05, -0.016, 0.0, 0.005, 0.014, 0.02, 0.1}) {
    const double fp = (z + h) / std::hypot(z + h, R), fm = (z - h) / std::hypot(z - h, R);
    const double inside = std::abs(z) < h ? 1.0 : 0.0;
    EXPECT_TRUE(close(c.field(Vec3(0, 0, z)), Vec3(kJ * (inside - 0.25 * (fp - fm)), 0, 0), kClosedFormTol)) << z;
  }
  // A long transversely magnetised rod has demagnetising factor 1/2: B at its centre → J/2.
  const CylinderMagnet rod(0.001, 2.0, Vec3(kJ, 0, 0));
  EXPECT_NEAR(rod.field(Vec3::Zero()).x(), 0.5 * kJ, 1e-6 * kJ);  // 1e-6: finite length, (R/h)² = 1e-6
}

TEST(Cylinder, MagpylibDocstringValues) {
  // Unit-J core functions of Magpylib (fields.md §3–4), printed there to 2–3 digits.
  // Axial, (z0, r, z) = (1, 1, 2) → (B_r, B_z) ≈ (0.056, 0.067); (2, 2, 3) → (0.041, 0.018).
  const CylinderMagnet a1(1.0, 2.0, Vec3(0, 0, 1)), a2(1.0, 4.0, Vec3(0, 0, 1));
  EXPECT_NEAR(a1.field(Vec3(1, 0, 2)).x(), 0.056, 6e-4);
  EXPECT_NEAR(a1.field(Vec3(1, 0, 2)).z(), 0.067, 6e-4);
  EXPECT_NEAR(a2.field(Vec3(2, 0, 3)).x(), 0.041, 6e-4);
  EXPECT_NEAR(a2.field(Vec3(2, 0, 3)).z(), 0.018, 6e-4);
  // Diametric, (z0, r, z, φ) = (1, 1, 2, 0.1) → (H_r, H_φ, H_z) ≈ (−0.021, 0.005, 0.055) per unit M.
  const CylinderMagnet d1(1.0, 2.0, Vec3(1, 0, 0));
  const double phi = 0.1;
  const Vec3 b = d1.field(Vec3(std::cos(phi), std::sin(phi), 2.0));
  const double br = b.x() * std::cos(phi) + b.y() * std::sin(phi);
  const double bphi = -b.x() * std::sin(phi) + b.y() * std::cos(phi);
  EXPECT_NEAR(br, -0.021, 6e-4);
  EXPECT_NEAR(bphi, 0.005, 6e-4);
  EXPECT_NEAR(b.z(), 0.055, 6e-4);
}

// Points (in units of R, h = 1.0 R for the thesis EPM) away from the surface by ≥ 0.2 R, covering the
// axis, the series branch of the diametric formula (ρ < 0.05 R), the edge extensions and the inside.
std::vector<Vec3> probe_points(double R, double h) {
  std::vector<Vec3> pts;
  for (double rho : {0.0, 0.003, 0.0199, 0.0201, 0.049, 0.3, 0.7, 1.0, 1.3, 2.0, 4.0}) {
    for (double z : {0.0, 0.4, 0.75, 1.25, 1.8, 3.5}) {
      const double zz = z * h;
      const double rr = rho * R;
      const bool near_side = std::abs(rr - R) < 0.2 * R && std::abs(zz) < h + 0.2 * R;
      const bool near_end = std::abs(std::abs(zz) - h) < 0.2 * R && rr < R + 0.2 * R;
      if (near_side || near_end) continue;
      const double phi = 0.3 + 1.7 * rho + z;  // arbitrary azimuths
      pts.emplace_back(rr * std::cos(phi), rr * std::sin(phi), zz);
      pts.emplace_back(rr * std::cos(phi + 2.0), rr * std::sin(phi + 2.0), -zz);
    }
  }
  return pts;
}

TEST(Cylinder, MatchesSurfaceSourceQuadrature) {
  // Axial J: Biot–Savart of the surface current; transverse J (incl. the series branch near the axis): Coulomb
  // field of the surface charge; oblique J: both.
  const double R = 0.02, L = 0.05;
  for (const Vec3& j : {Vec3(0, 0, 1.0), Vec3(1.0, 0, 0), Vec3(0.3, -0.8, 0.5)}) {
    const CylinderMagnet c(R, L, j);
    for (const Vec3& p : probe_points(R, 0.5 * L)) {
      EXPECT_TRUE(close(c.field(p), cylinder_field_quadrature(c, p), kQuadratureTol, 1e-12))
          << "J = " << j.transpose() << ", p/R = " << (p / R).transpose();
    }
  }
}

TEST(Cylinder, GeneralPolarisationIsSumOfParts) {
  // J = (Jx, Jy, Jz): the field is the axial part plus the transverse part, and rotating the transverse
  // polarisation about the axis equals rotating the observer the other way.
  const double R = 0.015, L = 0.02;
  const Vec3 j(0.3, -0.8, 0.5);
  const CylinderMagnet all(R, L, j), ax(R, L, Vec3(0, 0, j.z())), tr(R, L, Vec3(std::hypot(j.x(), j.y()), 0, 0));
  const double theta = std::atan2(j.y(), j.x());
  const Mat3 rz = Eigen::AngleAxisd(theta, Vec3::UnitZ()).toRotationMatrix();
  for (const Vec3& p : probe_points(R, 0.5 * L)) {
    const FieldSample s = all.field_gradient(p);
    const FieldSample a = ax.field_gradient(p);
    const FieldSample t = tr.field_gradient(rz.transpose() * p);
    EXPECT_TRUE(close(s.b, Vec3(a.b + rz * t.b), 1e-13, 1e-16));
    // The two sides evaluate at points that differ by the rounding of a rotation; near the axis B_ρ/ρ amplifies it.
    EXPECT_TRUE(close(flat(s.g), flat(a.g + rz * t.g * rz.transpose()), 1e-10, 1e-14));
  }
}

TEST(Cylinder, GradientMatchesFiniteDifferences) {
  const double R = 0.0508, L = 0.1016;
  for (const Vec3& j : {Vec3(0, 0, kJ), Vec3(kJ, 0, 0), Vec3(0.4, 0.9, -0.7)}) {
    const CylinderMagnet c(R, L, j);
    for (const Vec3& p : probe_points(R, 0.5 * L)) {
      const Mat3 fd = fd_gradient(c, p, kFdStep * R);
      const Mat3 g = c.field_gradient(p).g;
      EXPECT_TRUE(close(flat(g), flat(fd), kFdTol, 1e-9)) << "J = " << j.transpose() << ", p/R = " << (p / R).transpose();
    }
  }
}

TEST(Cylinder, GradientSymmetricTracelessOffTheSurface) {
  // curl B = 0 and div B = 0 inside and outside a uniformly magnetised body (bound currents sit on the surface).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  const CylinderMagnet c(0.01, 0.03, Vec3(0.2, -0.5, 1.1));
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p = Vec3(u(rng), u(rng), u(rng)) * 0.01;
    const Mat3 g = c.field_gradient(p).g;
    const double scale = g.norm();
    EXPECT_LE(std::abs(g.trace()), 1e-11 * scale) << p.transpose();
    EXPECT_LE((g - g.transpose()).norm(), 1e-11 * scale) << p.transpose();
  }
}

TEST(Cylinder, SymmetryOfAxialAndDiametricFields) {
  const CylinderMagnet ax(0.02, 0.03, Vec3(0, 0, 1)), di(0.02, 0.03, Vec3(1, 0, 0));
  const Vec3 p(0.013, 0.021, 0.017);
  // Axial: rotation about z commutes with the field; z → −z keeps B_z, flips B_x, B_y.
  const Mat3 rz = Eigen::AngleAxisd(0.77, Vec3::UnitZ()).toRotationMatrix();
  EXPECT_TRUE(close(ax.field(rz * p), Vec3(rz * ax.field(p)), 1e-13));
  const Vec3 a = ax.field(p), am = ax.field(Vec3(p.x(), p.y(), -p.z()));
  EXPECT_TRUE(close(am, Vec3(-a.x(), -a.y(), a.z()), 1e-13));
  // Diametric along x: y → −y flips B_y; z → −z flips B_z; x → −x flips B_y and B_z.
  const Vec3 d = di.field(p);
  EXPECT_TRUE(close(di.field(Vec3(p.x(), -p.y(), p.z())), Vec3(d.x(), -d.y(), d.z()), 1e-13));
  EXPECT_TRUE(close(di.field(Vec3(p.x(), p.y(), -p.z())), Vec3(d.x(), d.y(), -d.z()), 1e-13));
  EXPECT_TRUE(close(di.field(Vec3(-p.x(), p.y(), p.z())), Vec3(d.x(), -d.y(), -d.z()), 1e-13));
}

TEST(Cylinder, NormalComponentContinuousAcrossSurfaces) {
  const double R = 0.02, h = 0.025, e = 1e-9;
  for (const Vec3& j : {Vec3(0, 0, 1.2), Vec3(1.2, 0, 0)}) {
    const CylinderMagnet c(R, 2 * h, j);
    for (double phi : {0.0, 0.9, 2.5}) {
      for (double z : {-0.6 * h, 0.0, 0.3 * h, 0.8 * h}) {
        const Vec3 n(std::cos(phi), std::sin(phi), 0.0);
        const Vec3 in = c.field(Vec3(0, 0, z) + (R - e) * n), out = c.field(Vec3(0, 0, z) + (R + e) * n);
        EXPECT_NEAR(in.dot(n), out.dot(n), 1e-6) << "side wall, J=" << j.transpose();
        const Vec3 t(-n.y(), n.x(), 0.0);
        // Tangential jump = J_t (bound surface current K = M × n): B_in − B_out = J − (J·n)n.
        const Vec3 jump = in - out;
        const Vec3 expected = j - j.dot(n) * n;
        EXPECT_NEAR(jump.z(), expected.z(), 1e-6);
        EXPECT_NEAR(jump.dot(t), expected.dot(t), 1e-6);
      }
    }
    for (double rho : {0.0, 0.4 * R, 0.9 * R}) {
      const Vec3 q(rho * 0.6, rho * 0.8, 0);
      const Vec3 in = c.field(q + Vec3(0, 0, h - e)), out = c.field(q + Vec3(0, 0, h + e));
      EXPECT_NEAR(in.z(), out.z(), 1e-6) << "end face";
      EXPECT_TRUE(close(Vec3(in - out), Vec3(j.x(), j.y(), 0.0), 0, 1e-6));
    }
  }
}

TEST(Cylinder, FarFieldApproachesDipoleAsInverseSquare) {
  // No quadrupole (z → −z symmetry): the relative deviation from the dipole falls as (R/r)².
  // On the axis, B_cyl/B_dip = 1 + (2h² − 1.5R²)/z² + O(z⁻⁴) (fields.md §6).
  const double R = 0.0508, h = 0.0508;
  for (const Vec3& j : {Vec3(0, 0, kJ), Vec3(kJ, 0, 0)}) {
    const CylinderMagnet c(R, 2 * h, j);
    const Vec3 m = c.dipole_moment();
    for (const Vec3& dir : {Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0.6, 0.3, 0.74).normalized()}) {
      double prev = 0.0;
      for (double r : {0.5, 1.0, 2.0, 4.0}) {
        const Vec3 p = r * dir;
        const double err = (c.field(p) - dipole_field(m, p)).norm() / dipole_field(m, p).norm();
        if (prev > 0.0) {
          EXPECT_NEAR(prev / err, 4.0, 0.25) << "r=" << r;  // (R/r)² → ratio 4 per doubling
        }
        prev = err;
      }
    }
  }
  const CylinderMagnet c(R, 2 * h, Vec3(0, 0, kJ));
  // The switch to the dipole at kFarFieldDiameters jumps by the dipole's own error there, 0.5 (R/z)² ≈ 1.3e-7 on
  // the axis (fields.md §6), plus what the closed form has lost to cancellation: measured 2.8e-7 in all.
  const double far = CylinderMagnet::kFarFieldDiameters * 2 * R;
  for (const Vec3& dir : {Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0.5, 0.5, 0.7).normalized()}) {
    const Vec3 in = c.field(0.99999 * far * dir), out = c.field(1.00001 * far * dir);
    EXPECT_TRUE(close(in, Vec3(out * std::pow(1.00001 / 0.99999, 3)), 5e-7)) << dir.transpose();
  }
  const double z = 2.0;
  const double ratio = c.field(Vec3(0, 0, z)).z() / dipole_field(c.dipole_moment(), Vec3(0, 0, z)).z();
  // The O(z⁻⁴) remainder, measured at z = 1 m as 2.6 (R/z)⁴, is 1.1e-6 here.
  EXPECT_NEAR(ratio - 1.0, (2 * h * h - 1.5 * R * R) / (z * z), 2e-6);
}

TEST(Cylinder, DegeneratePlacesAreFinite) {
  const double R = 0.02, h = 0.015;
  const CylinderMagnet c(R, 2 * h, Vec3(0.7, 0.2, 1.1));
  std::vector<Vec3> pts = {
      Vec3(0, 0, 0),        Vec3(R, 0, h),         Vec3(0, R, -h),         Vec3(R, 0, 0),  // centre, rims, side wall
      Vec3(0, 0, h),        Vec3(0.5 * R, 0, -h),  Vec3(R, 0, 2 * h),      Vec3(2 * R, 0, h),  // faces, edge extensions
      Vec3(0, 0, 1e6),      Vec3(1e6, 1e6, 1e6),   Vec3(R * (1 + 1e-15), 0, h), Vec3(1e-300, 0, 0.5 * h)};
  for (const Vec3& p : pts) {
    const FieldSample s = c.field_gradient(p);
    EXPECT_TRUE(s.b.allFinite() && s.g.allFinite()) << p.transpose();
  }
  // Rim: reported as zero (the true field diverges logarithmically).
  EXPECT_EQ(c.field_gradient(Vec3(R, 0, h)).b.norm(), 0.0);
  // Very far: the dipole.
  const Vec3 far(3e2, -1e2, 5e2);
  EXPECT_TRUE(close(c.field(far), dipole_field(c.dipole_moment(), far), 1e-9));
  // Dense grid through every special surface: never NaN.
  for (double x : {0.0, 0.5 * R, R, 1.5 * R}) {
    for (double z : {0.0, 0.5 * h, h, 2 * h}) {
      for (double y : {0.0, R}) {
        const FieldSample s = c.field_gradient(Vec3(x, y, z));
        EXPECT_TRUE(s.b.allFinite() && s.g.allFinite()) << x << " " << y << " " << z;
      }
    }
  }
}

TEST(Cylinder, NearAxisGradientIsSmooth) {
  // The axis limit B_r/ρ → −½∂B_z/∂z and the series branch of the transverse part must join the general
  // formulas without a visible step: compare points just below and above each switch.
  const double R = 0.02;
  const CylinderMagnet c(R, 0.04, Vec3(0.6, 0.0, 0.9));
  for (double r_switch : {CylinderMagnet::kAxisLimit, CylinderMagnet::kSeriesRadius}) {
    const Vec3 lo(r_switch * R * (1 - 1e-9), 0, 0.7 * R), hi(r_switch * R * (1 + 1e-9), 0, 0.7 * R);
    const FieldSample a = c.field_gradient(lo), b = c.field_gradient(hi);
    EXPECT_TRUE(close(a.b, b.b, 1e-9)) << r_switch;
    EXPECT_TRUE(close(flat(a.g), flat(b.g), 1e-7)) << r_switch;
  }
}

}  // namespace
}  // namespace magvine::magnetics
