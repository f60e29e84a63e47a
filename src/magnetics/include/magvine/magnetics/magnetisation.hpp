#pragma once
/// Magnetisation laws of robot material (PHYSICS.md §2) and the wrench on a moment (thesis eq 1.3–1.4): the only
/// home of these laws. The robot (rod, vine, growth) and the MPM solver build on them.
///
/// Body frame of every rod and vine section (one convention across magvine): x = d1 along the centreline towards
/// the tip, y = d2 the base normal carried along the body, z = d3 = x × y. `body_to_world` is the section's frame R
/// (columns d1, d2, d3): a body-frame vector v is R v in the world.

#include <cmath>

#include <Eigen/Core>

#include "magvine/core/eigen_types.hpp"
#include "magvine/core/units.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::magnetics {

inline constexpr double kIronSaturation = 1.7e6;             ///< M_s of carbonyl iron [A/m] (PHYSICS.md §2)
inline constexpr double kIronDensity = 7870.0;               ///< [kg/m³]
inline constexpr double kBulkIronSusceptibility = 4999.0;    ///< χ of bulk iron (thesis eq 5.3)

/// Force and torque on a magnetic element, world frame.
struct Wrench {
  Vec3 force = Vec3::Zero();   ///< F = Gᵀ m, i.e. F_j = Σ_i m_i ∂B_i/∂x_j [N]
  Vec3 torque = Vec3::Zero();  ///< τ = m × B [N·m]
};

/// The gradient force on a moment, F = Gᵀm (thesis eq 1.4), in any dimension (the MPM's 2D grid takes the x–y block
/// of G). G_ij = ∂B_i/∂x_j [T/m], m [A·m²] → [N].
template <int D>
Eigen::Matrix<double, D, 1> gradient_force(const Eigen::Matrix<double, D, D>& g,
                                           const Eigen::Matrix<double, D, 1>& m) {
  return g.transpose() * m;
}

/// Wrench on moment m [A·m², world] in the field sample (B, G) [world]: τ = m × B, F = Gᵀm (thesis eq 1.3–1.4).
inline Wrench magnetic_wrench(const Vec3& m, const FieldSample& field) {
  return {gradient_force<3>(field.g, m), m.cross(field.b)};
}

/// Hard-magnetic material (NdFeB-silicone, a permanent magnet): m = Br·V/μ0, Br the remanence (polarisation J for a
/// magnet) as it points now [T], V the volume [m³]. Br is fixed in the material: a rigid section carries R·Br_body, a
/// deformed MPM particle F·B̃r (thesis eq 3.15). Any dimension.
template <int D>
Eigen::Matrix<double, D, 1> hard_magnetic_moment(const Eigen::Matrix<double, D, 1>& remanence, double volume) {
  return remanence * (volume / kMu0);
}

/// The same for a rigid section of body-frame remanence `br_body` turned by `body_to_world` [A·m², world].
inline Vec3 hard_magnetic_moment(const Vec3& br_body, double volume, const Mat3& body_to_world) {
  return hard_magnetic_moment<3>(Vec3(body_to_world * br_body), volume);
}

/// The hard-magnetic stress of Zhao et al. (2019), thesis eq 3.13: the first Piola–Kirchhoff stress
/// P_mag = −(1/μ0) B ⊗ B̃r (B̃r referential) [Pa] (what the total-Lagrangian MPM step uses).
template <int D>
Eigen::Matrix<double, D, D> hard_magnetic_piola_stress(const Eigen::Matrix<double, D, 1>& b,
                                                       const Eigen::Matrix<double, D, 1>& br) {
  return (-1.0 / kMu0) * b * br.transpose();
}

/// The same stress as the Kirchhoff stress P_mag Fᵀ = −B ⊗ (F B̃r)/μ0 the updated-Lagrangian MPM step uses
/// (`f_br` = F B̃r) [Pa].
template <int D>
Eigen::Matrix<double, D, D> hard_magnetic_kirchhoff_stress(const Eigen::Matrix<double, D, 1>& b,
                                                           const Eigen::Matrix<double, D, 1>& f_br) {
  return hard_magnetic_piola_stress<D>(b, f_br);  // P_mag Fᵀ = −B (F B̃r)ᵀ/μ0: eq 3.13 with F B̃r for B̃r
}

/// The hard-magnetic energy density whose derivative in F is P_mag = −B B̃rᵀ/μ0 (Zhao et al. 2019; thesis 3.3),
/// ψ_mag = −(F B̃r) · B / μ0 [J/m³ of the reference] (`f_br` = F B̃r): linear in F.
template <int D>
double hard_magnetic_energy_density(const Eigen::Matrix<double, D, 1>& b, const Eigen::Matrix<double, D, 1>& f_br) {
  return -f_br.dot(b) / kMu0;
}

/// Rigid permanent magnet at the tip (thesis table 5.1): cylinder of given size, J along `direction_body`. (No robot
/// carries one yet; a rod's magnetised tip section is the same law.)
struct MagnetTip {
  double diameter = 0.0;                 ///< [m]
  double length = 0.0;                   ///< [m]
  double polarisation = 0.0;             ///< J [T]
  Vec3 direction_body = Vec3::UnitX();   ///< unit magnetisation direction, body frame (x: along the body)

  double volume() const;
  /// m = J V/μ0 along the rotated direction [A·m², world].
  Vec3 moment(const Mat3& body_to_world) const;
};

/// Magnetic skin on an everting vine (thesis 4.4.2, eq 4.1–4.2, 5.1–5.2).
///
/// The outer (everted) layer keeps its remanence Br in the body frame. Eversion turns each wall element over by a
/// half-turn about its circumferential direction, so in the inverted tail the radial and axial components of the
/// remanence change sign and the tangential one is kept; averaged round the circumference the transverse part
/// rotates by 2φ and vanishes, the axial part (x) flips: tail = (1/2π)∫ R_x(2φ) diag(−1, −1, 1) Br dφ = (−Br_x, 0, 0).
/// (Thesis eq 4.2 omits the flip but states this result: axial magnetisation nets 0, orthogonal magnetisation keeps
/// the outer moment.)
struct SkinLaw {
  double radius = 0.0;               ///< vine radius R [m]
  double thickness = 0.0;            ///< skin thickness w [m]
  Vec3 br_body = Vec3::Zero();       ///< remanence of the outer layer, body frame [T]

  /// Cross-section area of the skin 2πRw [m²] (thin-wall).
  double area() const;
  /// Moment of the everted layer per unit length, body frame [A·m²/m = A·m].
  Vec3 outer_moment_per_length() const;
  /// Moment of the inverted tail per unit length, body frame [A·m].
  Vec3 tail_moment_per_length() const;
  /// Net moment per unit length where the tail runs inside the everted body (with_tail) or not [A·m]. An everting
  /// vine's tail runs inside its whole everted length.
  Vec3 moment_per_length(bool with_tail) const;
};

/// A soft-magnetic material that magnetises along the local field (a magnetic fluid), as the co-energy density of
/// the field in its body frame [beyond the thesis; PHYSICS.md §2]: with H = B/μ0 and X = diag(χ_axial, χ_transverse,
/// χ_transverse) (demagnetisation included),
///   e(B) = −μ0 (M_s²/χ_ref) ln cosh(√(χ_ref HᵀXH)/M_s)   [J/m³],
/// and M = −de/dB = M_s tanh(y/M_s)/y · XH with y = √(χ_ref HᵀXH). Weak fields: e = −½μ0HᵀXH, M = XH (linear);
/// strong fields: |M| → M_s along the axis (|M| ≤ M_s in every direction for X ≤ χ_ref). A body of volume V then has
/// U = V e(RᵀB), so its moment is m = V R M, its force Gᵀm and its torque m × B. The law is a potential: the work
/// ∮M·dB round any closed path is zero, as a minimisation needs (the "direction of XH, magnitude M_s tanh(|XH|/M_s)"
/// form is not, for X anisotropic). M_s = ∞ gives the linear law.
struct InducedMagnetisation {
  double axial_susceptibility = 0.0;      ///< χ_axial, along the body (x)
  double transverse_susceptibility = 0.0; ///< χ_transverse, across (y, z)
  double saturation = 0.0;                ///< M_s [A/m]; ∞: linear
  double reference_susceptibility = 1.0;  ///< χ_ref of the saturation form (> 0)

  /// e(b) at body-frame field b [T] → [J/m³]; de/db (= −M [A/m]) into `derivative`, d²e/db² into `second` when given.
  double energy_density(const Vec3& b, Vec3& derivative, Mat3* second = nullptr) const;
  /// M = −de/db at body-frame field b [A/m, body frame].
  Vec3 magnetisation(const Vec3& b) const;
  /// Moment of volume V [m³] in world field b [T] of a body turned by `body_to_world` [A·m², world].
  Vec3 moment(const Vec3& b, double volume, const Mat3& body_to_world) const;
};

namespace detail {
/// ln cosh z for z ≥ 0 without overflow.
inline double log_cosh(double z) { return z + std::log1p(std::exp(-2.0 * z)) - std::log(2.0); }
}  // namespace detail

// Inline: the rod solver's hot kernel evaluates it for every edge of every Newton trial.
inline double InducedMagnetisation::energy_density(const Vec3& b, Vec3& derivative, Mat3* second) const {
  const Vec3 chi(axial_susceptibility, transverse_susceptibility, transverse_susceptibility);
  const Vec3 xb = chi.cwiseProduct(b);
  const double quadratic = b.dot(xb) / kMu0;                           // μ0 HᵀXH
  const double y = std::sqrt(reference_susceptibility * quadratic / kMu0);  // √(χ_ref HᵀXH) [A/m]
  const double z = y / saturation;
  if (!std::isfinite(saturation) || z < 1e-8) {
    // Linear (or below the saturation form's resolution): e = −½ BᵀXB/μ0.
    derivative = -xb / kMu0;
    if (second != nullptr) *second = Mat3((-chi / kMu0).asDiagonal());
    return -0.5 * quadratic;
  }
  const double tanh_z = std::tanh(z);
  const double scale = saturation * tanh_z / (kMu0 * y);
  derivative = -scale * xb;
  if (second != nullptr) {
    // de/db = −s(y)Xb with s = M_s tanh(y/M_s)/(μ0 y); ds/dy · dy/db = [(1 − tanh² z) − tanh z/z]/(μ0 y) · χ_ref Xb/(μ0² y).
    const double ds =
        ((1.0 - tanh_z * tanh_z) - tanh_z / z) / (kMu0 * y) * reference_susceptibility / (kMu0 * kMu0 * y);
    *second = Mat3((-scale * chi).asDiagonal()) - ds * xb * xb.transpose();
  }
  return -kMu0 * saturation * saturation / reference_susceptibility * detail::log_cosh(z);
}

/// Magnetic fluid, thesis law (eq 5.3): m = σ χ H V with H = B/μ0, σ the iron volume fraction and χ the susceptibility
/// of bulk iron. Kept to reproduce thesis figure 5.2; it ignores demagnetisation and saturation and overestimates the
/// moment by about three orders of magnitude (PHYSICS.md §2).
struct FluidThesisLaw {
  double volume_fraction = 0.23;          ///< σ
  double chi = kBulkIronSusceptibility;   ///< χ of bulk iron

  /// As an induced magnetisation: isotropic σχ, linear.
  InducedMagnetisation induced() const;
  /// Induced moment for field b [T, world] in fluid volume V [m³]; parallel to B (no torque).
  Vec3 moment(const Vec3& b, double volume) const;
};

/// Magnetic fluid, bounded physical law [beyond the thesis; PHYSICS.md §2]:
///  - suspension susceptibility from Maxwell-Garnett, χ_s = 3φβ/(1 − φβ), β = (μ_p − 1)/(μ_p + 2) = χ_p/(χ_p + 3)
///    (β → 1 for highly permeable particles: μ_s = (1 + 2φ)/(1 − φ));
///  - shape demagnetisation of the fluid column in the body frame: χ_i = χ_s/(1 + N_i χ_s) (long cylinder: N = 0
///    along the axis x, N = 1/2 across);
///  - saturation at φ·M_s of the particles, in the co-energy form of InducedMagnetisation with χ_ref = χ_s (so the
///    axial magnetisation saturates at φ·M_s exactly; across, at φ·M_s·√(χ_transverse/χ_s), 0.83 φ·M_s at φ = 0.23).
/// The force on the induced moment follows from U = −½ m·B in weak fields and is again F = Gᵀm; the anisotropy gives a
/// small aligning torque m × B.
struct FluidBoundedLaw {
  double volume_fraction = 0.23;                          ///< φ, iron volume fraction
  double particle_susceptibility = kBulkIronSusceptibility;  ///< χ_p of the particles
  double saturation = kIronSaturation;                    ///< M_s of the particle material [A/m]
  double demag_axial = 0.0;                               ///< N along the body axis (x)
  double demag_transverse = 0.5;                          ///< N across the body axis

  /// χ_s of the suspension (Maxwell-Garnett).
  double suspension_susceptibility() const;
  /// As an induced magnetisation (the law the rod and vine use).
  InducedMagnetisation induced() const;
  /// Induced moment for field b [T, world] in fluid volume V [m³], column oriented by body_to_world.
  Vec3 moment(const Vec3& b, double volume, const Mat3& body_to_world) const;
};

/// The yield stress τ_y [Pa] of a magnetorheological fluid of iron volume fraction φ in an applied field H [A/m]:
/// τ_y(H) = min(√6·φ·μ0·M_s^½·H^{3/2}, 0.086·φ·μ0·M_s²) (Ginder & Davis 1994: chains of saturating iron spheres,
/// intermediate fields, capped at saturation), M_s = kIronSaturation.
double magnetorheological_yield_stress(double field_strength, double volume_fraction);

}  // namespace magvine::magnetics
