#pragma once
/// Point dipole field and gradient (PHYSICS.md §1, fields.md §6).

#include <cmath>

#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::magnetics {

/// Below this distance from a point dipole [m] the field is reported as zero instead of diverging.
inline constexpr double kDipoleCoreRadius = 1e-9;

/// B at offset r = x − p from a dipole of moment m [A·m²]:  B = μ0/(4π|r|³)(3 r̂ r̂ᵀ − I) m  [T].
inline Vec3 dipole_field(const Vec3& m, const Vec3& r) {
  const double d2 = r.squaredNorm();
  if (d2 < kDipoleCoreRadius * kDipoleCoreRadius) return Vec3::Zero();
  const double inv_d = 1.0 / std::sqrt(d2);
  const Vec3 rh = r * inv_d;
  const double k = kMu0 / (4.0 * kPi) * inv_d * inv_d * inv_d;
  return k * (3.0 * rh.dot(m) * rh - m);
}

/// B and G_ij = ∂B_i/∂x_j of a dipole:  G = 3μ0/(4π|r|⁴)( m r̂ᵀ + r̂ mᵀ + (r̂·m)(I − 5 r̂ r̂ᵀ) ).
inline FieldSample dipole_field_gradient(const Vec3& m, const Vec3& r) {
  FieldSample out;
  const double d2 = r.squaredNorm();
  if (d2 < kDipoleCoreRadius * kDipoleCoreRadius) return out;
  const double inv_d = 1.0 / std::sqrt(d2);
  const Vec3 rh = r * inv_d;
  const double rm = rh.dot(m);
  const double k = kMu0 / (4.0 * kPi) * inv_d * inv_d * inv_d;
  out.b = k * (3.0 * rm * rh - m);
  const double kg = 3.0 * k * inv_d;
  out.g.noalias() = kg * (m * rh.transpose() + rh * m.transpose() - 5.0 * rm * rh * rh.transpose());
  out.g.diagonal().array() += kg * rm;
  return out;
}

/// The direction of a dipole's moment (unnormalised) whose field at unit offset r̂ (from the dipole) points along b:
/// B ∝ (3r̂r̂ᵀ − I)m, whose inverse is (3r̂r̂ᵀ − I)⁻¹ = (3/2)r̂r̂ᵀ − I, so m ∝ (3/2)(b·r̂)r̂ − b. Zero never (|m| ≥ |b|/2).
inline Vec3 dipole_moment_for_field(const Vec3& r_hat, const Vec3& b) { return 1.5 * b.dot(r_hat) * r_hat - b; }

/// The Hessian of w·B in x (w a fixed vector), Σ_i w_i ∂²B_i/∂x∂x, of a dipole: with a = m·r̂, c = w·r̂ and d = |r|,
///   μ0/(4πd⁵)[3(m wᵀ + w mᵀ + (m·w)I) − 15((c m + a w)r̂ᵀ + r̂(c m + a w)ᵀ + ac I + (m·w)r̂r̂ᵀ) + 105 ac r̂r̂ᵀ],
/// symmetric and traceless (w·B is harmonic away from the dipole). The curvature term of a magnet's energy −m·B.
inline Mat3 dipole_field_curvature(const Vec3& m, const Vec3& r, const Vec3& w) {
  const double d2 = r.squaredNorm();
  if (d2 < kDipoleCoreRadius * kDipoleCoreRadius) return Mat3::Zero();
  const double inv_d = 1.0 / std::sqrt(d2);
  const Vec3 rh = r * inv_d;
  const double a = rh.dot(m);
  const double c = rh.dot(w);
  const double mw = m.dot(w);
  const Vec3 v = c * m + a * w;
  Mat3 h = 3.0 * (m * w.transpose() + w * m.transpose()) - 15.0 * (v * rh.transpose() + rh * v.transpose()) +
           (105.0 * a * c - 15.0 * mw) * (rh * rh.transpose());
  h.diagonal().array() += 3.0 * mw - 15.0 * a * c;
  return kMu0 / (4.0 * kPi) * inv_d * inv_d * inv_d * inv_d * inv_d * h;
}

}  // namespace magvine::magnetics
