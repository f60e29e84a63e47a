#!/usr/bin/env python3
"""How much the Zhao beam's own weight moves its deflection: the antiparallel cantilever elastica with gravity along
the beam (docs/validation.md, "Zhao beam: plane strain, plane stress or 3D").

    θ'' = −B̄ sin θ + σ γ (1 − ξ) sin θ,   θ(0) = 0, θ'(1) = 0,   δ/L = ∫₀¹ sin θ dξ

B̄ = 12 (L/t)² Br B / (μ0 E) is the magnetic load (antiparallel field: Euler's elastica under an axial dead load,
notes §9) and γ = ρ g A L³ / (E I) = 12 ρ g L³ / (E t²) the weight, carried as an axial force q (L − s) by the section
at arc length s: σ = +1 for a beam hanging from its clamp (the weight pulls it straight), −1 for one standing on it,
0 without gravity (the closed form: studies::antiparallel_elastica_deflection). Solved by shooting on θ'(0) for the first
mode (θ monotone; the largest root: higher modes start slower), with scipy's RK45 at rtol 1e-10, δ/L integrated
as a third state of the ODE. The beam's data are the study's (L 17.2 mm, t 0.84 mm,
G 303 kPa, K = 20 G, Br 0.143 T, ρ 2000 kg/m³ assumed), E or E/(1 − ν²) as the bending modulus.

Usage: /usr/bin/python3 tools/zhao_gravity_elastica.py [--density RHO] [--csv FILE]
"""
import argparse
import csv
import math
import sys

try:
    import numpy as np
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq
    from scipy.special import ellipk
except ImportError as e:  # pragma: no cover
    sys.exit(f"zhao_gravity_elastica.py: needs numpy and scipy ({e})")

LENGTH, THICKNESS, SHEAR, REMANENCE, MU0 = 17.2e-3, 0.84e-3, 303e3, 0.143, 4e-7 * math.pi
FIELDS_MT = (5, 7, 10, 15, 25, 40)


def tip_slope_rate(rate, bbar, gamma, sense):
    """θ'(1) for a start θ'(0) = rate, and the solution (θ, θ', ∫ sin θ)."""
    def rhs(x, y):
        return [y[1], (-bbar + sense * gamma * (1.0 - x)) * math.sin(y[0]), math.sin(y[0])]
    sol = solve_ivp(rhs, (0.0, 1.0), [0.0, rate, 0.0], rtol=1e-10, atol=1e-12, dense_output=True)
    return sol.y[1, -1], sol


def deflection(bbar, gamma, sense):
    """δ/L of the first buckled mode (θ monotone: the largest root θ'(0); higher modes start slower); 0 where only
    the straight beam is in equilibrium."""
    top = 2.0 * math.sqrt(bbar + gamma) + 1.0
    rates = np.linspace(1e-4, top, 400)
    ends = [tip_slope_rate(r, bbar, gamma, sense)[0] for r in rates]
    for i in reversed(range(len(rates) - 1)):
        if ends[i] * ends[i + 1] < 0.0:
            rate = brentq(lambda r: tip_slope_rate(r, bbar, gamma, sense)[0], rates[i], rates[i + 1], xtol=1e-12)
            sol = tip_slope_rate(rate, bbar, gamma, sense)[1]
            if np.min(sol.sol(np.linspace(0.0, 0.999, 1000))[1]) < -1e-9:
                sys.exit(f"zhao_gravity_elastica.py: the root found at B̄ {bbar:.3f} is not the first mode")
            return float(sol.y[2, -1])
    return 0.0


def closed_form(bbar):
    """Without gravity: √B̄ = K(k), δ/L = 2k / K(k) (notes §9), k by bisection; 0 below B̄c = π²/4."""
    if math.sqrt(bbar) <= 0.5 * math.pi:
        return 0.0
    lo, hi = 0.0, 1.0
    for _ in range(200):
        k = 0.5 * (lo + hi)
        lo, hi = (k, hi) if ellipk(k * k) < math.sqrt(bbar) else (lo, k)
    k = 0.5 * (lo + hi)
    return 2.0 * k / ellipk(k * k)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--density", type=float, default=2000.0, help="kg/m³ (default 2000, the study's assumption)")
    ap.add_argument("--csv", help="also write the table here")
    a = ap.parse_args()
    if not a.density > 0.0:
        sys.exit("zhao_gravity_elastica.py: --density must be > 0")
    bulk = 20.0 * SHEAR
    young = 9.0 * bulk * SHEAR / (3.0 * bulk + SHEAR)
    nu = (3.0 * bulk - 2.0 * SHEAR) / (2.0 * (3.0 * bulk + SHEAR))
    rows = []
    worst = 0.0
    for name, modulus in (("E", young), ("E/(1-nu^2)", young / (1.0 - nu * nu))):
        gamma = 12.0 * a.density * 9.81 * LENGTH ** 3 / (modulus * THICKNESS ** 2)
        for b in FIELDS_MT:
            bbar = 12.0 * (LENGTH / THICKNESS) ** 2 * REMANENCE * b * 1e-3 / (MU0 * modulus)
            free = deflection(bbar, gamma, 0)
            worst = max(worst, abs(free - closed_form(bbar)))
            rows.append({"modulus": name, "gamma": round(gamma, 4), "field_mT": b, "bbar": round(bbar, 4),
                         "no_gravity": round(free, 4),
                         "hanging": round(deflection(bbar, gamma, +1), 4),
                         "standing": round(deflection(bbar, gamma, -1), 4)})
    print(f"shooting without gravity against the closed form: largest difference {worst:.1e}")
    if worst > 1e-6:  # the ODE's tolerance is 1e-10; the shooting's brentq 1e-12
        sys.exit("zhao_gravity_elastica.py: the shooting does not reproduce the closed-form elastica")
    print("modulus      gamma  field  bbar    delta/L: none  hanging  standing")
    for r in rows:
        print(f"{r['modulus']:<12} {r['gamma']:.3f} {r['field_mT']:>4} mT {r['bbar']:6.3f}   {r['no_gravity']:.4f}   "
              f"{r['hanging']:.4f}   {r['standing']:.4f}")
    if a.csv:
        with open(a.csv, "w", encoding="utf-8", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
