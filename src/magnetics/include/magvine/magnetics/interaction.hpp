#pragma once
/// The force and torque between two permanent magnets (the dEPM platform's two EPMs, thesis chapter 4): the exact
/// cylinder field of one integrated over the other. Two independent forms of the same integral, one used at run time
/// and one that checks it (docs/platform.md):
///  - surface charges (used): a uniformly magnetised body of magnetisation M in an external field B carries the
///    charge σ = M·n̂ on its surface and none inside (∇·M = 0), so F = ∮ σ B dA and, about its centre c,
///    τ = ∮ σ (x − c) × B dA (the charge pairs carry the couple m × B themselves: ∮ σ x dA = ∫ M dV);
///  - volume (check): F = ∫ ∇(M·B) dV = ∫ Gᵀ M dV and τ = ∫ [(x − c) × Gᵀ M + M × B] dV, with the analytic gradient.
/// Far apart both tend to the dipole–dipole law F = Gᵀ(m_a) m_b (magnetic_wrench with the dipole field).
/// Gauss–Legendre in the radius and along the axis, the trapezoid rule round the circumference (periodic: spectrally
/// accurate). Quadrature needs the source's field smooth over the target: the magnets must not overlap.

#include "magvine/magnetics/cylinder.hpp"
#include "magvine/magnetics/magnetisation.hpp"
#include "magvine/magnetics/pose.hpp"

namespace magvine::magnetics {

/// Nodes of the magnet–magnet quadrature. The default errs by < 1e-6 (relative to the force) once the gap between
/// the magnets exceeds a fifth of their radius (test_interaction measures it against a much finer rule).
struct InteractionResolution {
  int radial = 12;   ///< Gauss–Legendre nodes across the radius
  int axial = 12;    ///< Gauss–Legendre nodes along the length
  int angular = 48;  ///< trapezoid nodes round the circumference
};

/// The wrench on `target` (at `target_pose`) in the field of `source` (at `source_pose`), world frame; the torque is
/// about the target's centre. Surface-charge form.
Wrench magnet_magnet_wrench(const CylinderMagnet& source, const Pose& source_pose, const CylinderMagnet& target,
                            const Pose& target_pose, const InteractionResolution& resolution = {});

/// The same by the volume form (the independent check of magnet_magnet_wrench).
Wrench magnet_magnet_wrench_volume(const CylinderMagnet& source, const Pose& source_pose, const CylinderMagnet& target,
                                   const Pose& target_pose, const InteractionResolution& resolution = {});

}  // namespace magvine::magnetics
