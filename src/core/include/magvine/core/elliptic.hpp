#pragma once
/// Complete elliptic integrals through Bulirsch's generalised integral `cel`
/// (R. Bulirsch, Numer. Math. 13, 305–315, 1969). Notes: shared/reference/fields.md §2.

namespace magvine {

/// cel(kc, p, c, s) = ∫_0^{π/2} (c cos²t + s sin²t) / ((cos²t + p sin²t) √(cos²t + kc² sin²t)) dt.
/// kc is the complementary modulus (any kc ≠ 0, also kc > 1, i.e. a negative parameter m = 1 − kc²);
/// p ≤ 0 gives the Cauchy principal value. kc = 0 diverges: the caller must not pass it (returns +inf).
double cel(double kc, double p, double c, double s);

/// The Gauss/Landen iteration of `cel` started from an arbitrary state (a, b, p, c, s) at the top of the loop.
/// Lets callers perform the first step analytically when it would cancel (Ortner et al. 2023, loop field).
double cel_iterate(double a, double b, double p, double c, double s);

/// K(m) = ∫ dt / √(1 − m sin²t), parameter m < 1 (m ≤ 0 allowed).
double ellip_k(double m);
/// E(m) = ∫ √(1 − m sin²t) dt, parameter m < 1 (m ≤ 0 allowed).
double ellip_e(double m);
/// Π(n, m) = ∫ dt / ((1 − n sin²t) √(1 − m sin²t)), m < 1; n > 1 gives the principal value.
double ellip_pi(double n, double m);

}  // namespace magvine
