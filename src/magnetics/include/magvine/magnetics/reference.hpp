#pragma once
/// Reference field of a uniformly magnetised cylinder by direct quadrature of its equivalent surface sources,
/// kept apart from the closed forms it checks (no elliptic integrals, no shared code):
///  - axial J_z: Biot–Savart of the side-wall surface current K = (J_z/μ0) φ̂;
///  - transverse J_⊥: Coulomb field of the side-wall surface charge σ = (J_⊥/μ0) cos(φ − θ), plus J_⊥ inside.
/// Trapezoid rule in φ (periodic, spectrally accurate) and composite Gauss–Legendre in z. Resolution is the knob
/// of the field-model convergence study (`magvine study field-models`); at the default it agrees with the closed
/// forms to ~1e-10 for points more than 0.2 R from the surface.

#include "magvine/magnetics/cylinder.hpp"

namespace magvine::magnetics {

struct QuadratureResolution {
  int n_phi = 720;     ///< trapezoid points round the circumference
  int z_panels = 40;   ///< Gauss–Legendre panels along the length
  int gauss_order = 16;  ///< nodes per panel
};

/// B [T] at local point p by quadrature.
Vec3 cylinder_field_quadrature(const CylinderMagnet& magnet, const Vec3& p, const QuadratureResolution& res = {});

}  // namespace magvine::magnetics
