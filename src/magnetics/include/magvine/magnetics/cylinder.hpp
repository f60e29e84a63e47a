#pragma once
/// Exact field of a uniformly magnetised solid cylinder, with its analytic gradient.
///
/// Local frame: centre at the origin, axis along z. The polarisation J = μ0·M [T] may point anywhere:
/// its axial part uses Derby & Olbert (Am. J. Phys. 78, 229, 2010), its transverse ("diametric") part
/// Caciagli et al. (JMMM 456, 423, 2018) with the small-radius series of Magpylib; all through Bulirsch's
/// `cel`. Gradient: the axial ∂B/∂z is the field of the two end-face current loops (Ortner et al.,
/// Magnetism 3, 11, 2023); the transverse ∂B/∂z follows from it by the symmetry of the third derivatives
/// of the cylinder's Newtonian potential (∂_z H_i[J x̂] = ∂_x H_i[J ẑ]); the remaining derivatives come from
/// curl B = 0 and div B = 0 in cylindrical coordinates. Derivation notes: fields.md §3–4 and docs/magnetics.md.
///
/// Degenerate places (all finite, never NaN):
///  - on the axis: exact limits (B_r = 0; the gradient uses the axis limit for B_r/ρ below ρ/R = kAxisLimit);
///  - on a rim edge (ρ = R, |z| = h, within 1e-14·R): B = 0 and G = 0 (the true field diverges
///    logarithmically, the gradient like 1/distance) — as Magpylib does;
///  - on the side wall or an end face exactly: the mean of the inside and outside limits;
///  - inside: B includes J (B = μ0(H + M)); G is the gradient of B;
///  - beyond kFarFieldDiameters diameters from the centre: the point dipole m = J·V/μ0, whose error there is
///    ~1e-7 while the closed forms have lost about as much to cancellation (the switch jumps by ~3e-7).

#include "magvine/magnetics/field_sample.hpp"

namespace magvine::magnetics {

class CylinderMagnet {
 public:
  /// Below ρ/R = kAxisLimit the axial B_r/ρ is replaced by its axis limit −½∂B_z/∂z (error O((ρ/R)²)).
  static constexpr double kAxisLimit = 1e-6;
  /// Below ρ/R = kSeriesRadius the transverse part uses its Taylor series. Measured series − general
  /// differences (per unit J): the O(r⁶) series errs by ~5e-10 at r = 0.05 (Magpylib's switch) and ~3e-8
  /// at 0.1; the general form loses digits like 1/r², ~1e-11 at r = 0.01 and ~1e-10 at 0.002. At 0.02 both
  /// are ~1e-12 in B and ~1e-10 in ρ·∂B/∂ρ, so the switch sits there.
  static constexpr double kSeriesRadius = 0.02;
  /// Beyond this many diameters (of the larger of diameter and length) the dipole approximation is used.
  static constexpr double kFarFieldDiameters = 1000.0;

  /// radius R [m] > 0, length L [m] > 0 (full length), polarisation J in the local frame [T].
  CylinderMagnet(double radius, double length, const Vec3& polarisation);

  double radius() const { return m_radius; }
  double length() const { return 2.0 * m_half_length; }
  const Vec3& polarisation() const { return m_j; }
  /// Volume π R² L [m³].
  double volume() const;
  /// Equivalent dipole moment J·V/μ0 [A·m²], local frame.
  const Vec3& dipole_moment() const { return m_dipole; }

  /// B at a local point [T].
  Vec3 field(const Vec3& p) const;
  /// B and G at a local point, local frame.
  FieldSample field_gradient(const Vec3& p) const;

 private:
  template <bool kWithGradient>
  FieldSample evaluate(const Vec3& p) const;

  double m_radius;
  double m_half_length;
  Vec3 m_j;
  double m_j_axial;        // J_z [T]
  double m_j_transverse;   // |(J_x, J_y)| [T]
  double m_cos_t, m_sin_t; // direction of the transverse part in the local xy plane
  double m_far_radius2;    // squared switch distance to the dipole model [m²]
  Vec3 m_dipole;           // J·V/μ0 [A·m²], local frame
};

}  // namespace magvine::magnetics
