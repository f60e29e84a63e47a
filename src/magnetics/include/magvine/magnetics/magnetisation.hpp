#pragma once
/// Magnetisation laws of robot material (PHYSICS.md §2) and the wrench on a moment (thesis eq 1.3–1.4).
///
/// Body frame convention for vine and rod cross-sections: e_z along the centreline (towards the tip),
/// e_x and e_y transverse. `body_to_world` rotates body-frame vectors into the world frame.

#include "magvine/core/eigen_types.hpp"
#include "magvine/magnetics/field_sample.hpp"

namespace magvine::magnetics {

/// Force and torque on a magnetic element, world frame.
struct Wrench {
  Vec3 force = Vec3::Zero();   ///< F = Gᵀ m, i.e. F_j = Σ_i m_i ∂B_i/∂x_j [N]
  Vec3 torque = Vec3::Zero();  ///< τ = m × B [N·m]
};

/// Wrench on moment m [A·m², world] in the field sample (B, G) [world].
Wrench magnetic_wrench(const Vec3& m, const FieldSample& field);

/// Hard-magnetic material (NdFeB-silicone): m = R · Br · V / μ0; Br is fixed in the body and rotates with it.
/// br_body [T, body frame], volume [m³].
Vec3 hard_magnetic_moment(const Vec3& br_body, double volume, const Mat3& body_to_world);

/// Rigid permanent magnet at the tip (thesis table 5.1): cylinder of given size, J along `direction_body`.
struct MagnetTip {
  double diameter = 0.0;                 ///< [m]
  double length = 0.0;                   ///< [m]
  double polarisation = 0.0;             ///< J [T]
  Vec3 direction_body = Vec3::UnitZ();   ///< unit magnetisation direction, body frame

  double volume() const;
  /// m = J V/μ0 along the rotated direction [A·m², world].
  Vec3 moment(const Mat3& body_to_world) const;
};

/// Magnetic skin on an everting vine (thesis 4.4.2, eq 4.1–4.2, 5.1–5.2).
///
/// The outer (everted) layer keeps its remanence Br in the body frame. Eversion turns each wall element
/// over by a half-turn about its circumferential direction, so in the inverted tail the radial and axial
/// components of the remanence change sign and the tangential one is kept; averaged round the
/// circumference the transverse part rotates by 2φ and vanishes, the axial part flips:
/// tail = (1/2π)∫ R_z(2φ) diag(−1, 1, −1) Br dφ = (0, 0, −Br_z). (Thesis eq 4.2 omits the flip but states
/// this result: axial magnetisation nets 0, orthogonal magnetisation keeps the outer moment.)
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
  /// Net moment per unit length where the tail runs inside the everted body (with_tail) or not [A·m].
  Vec3 moment_per_length(bool with_tail) const;
};

/// Magnetic fluid, thesis law (eq 5.3): m = σ χ H V with H = B/μ0, σ the iron volume fraction and χ the
/// susceptibility of bulk iron. Kept to reproduce thesis figure 5.2; it ignores demagnetisation and
/// saturation and overestimates the moment by about three orders of magnitude (PHYSICS.md §2).
struct FluidThesisLaw {
  double volume_fraction = 0.23;  ///< σ
  double chi = 4999.0;            ///< χ of bulk iron

  /// Induced moment for field b [T, world] in fluid volume V [m³]; parallel to B (no torque).
  Vec3 moment(const Vec3& b, double volume) const;
};

/// Magnetic fluid, bounded physical law [beyond the thesis; PHYSICS.md §2]:
///  - suspension susceptibility from Maxwell-Garnett, χ_s = 3φβ/(1 − φβ), β = (μ_p − 1)/(μ_p + 2);
///  - shape demagnetisation of the fluid column in the body frame: M_i = χ_s/(1 + N_i χ_s) H_i
///    (long cylinder: N_z = 0 along the axis, N_x = N_y = 1/2 across);
///  - smooth saturation at φ·Ms: |M| = Ms_s tanh(|M_lin|/Ms_s), direction of M_lin kept.
/// The force on the induced moment follows from U = −½ m·B and is again F = Gᵀm; the anisotropy gives a
/// small aligning torque m × B.
struct FluidBoundedLaw {
  double volume_fraction = 0.23;         ///< φ, iron volume fraction
  double particle_susceptibility = 4999; ///< χ_p of the particles
  double saturation = 1.7e6;             ///< Ms of the particle material [A/m] (iron)
  double demag_axial = 0.0;              ///< N along the body axis
  double demag_transverse = 0.5;         ///< N across the body axis

  /// χ_s of the suspension (Maxwell-Garnett).
  double suspension_susceptibility() const;
  /// Induced moment for field b [T, world] in fluid volume V [m³], column oriented by body_to_world.
  Vec3 moment(const Vec3& b, double volume, const Mat3& body_to_world) const;
};

}  // namespace magvine::magnetics
