#!/usr/bin/python3
"""Thesis fig 3.5 as a sweep: the gradient-extension robot's extension against its distance to the magnet.

The robot of assets/scenes/mpm_gradient_extension.yaml (thesis 3.6.3: Ecoflex-30/NdFeB, G 33 kPa, Br 0.101 T, thick
and thin rings of radius 5 and 2.5 mm, axially magnetised) hangs from its clamp above the Ø100 × 100 mm magnet
(J 1.44 T). The thesis lowered it towards the magnet on a linear stage and measured the extension at each height;
here the magnet is placed at each distance in turn (the gap between the robot's free end and the magnet's top face)
and `magvine mpm` runs the scene until it settles: a quasi-static sweep, each point an equilibrium (a stage moved
slowly enough; a moving clamp at 50 mm/s overshot, docs/mpm.md).

The thesis gives fig 3.5 without numbers (its text: simulation and experiment "in strong agreement", the error
larger at lower distances). Beside each MPM point, an independent 1D estimate: the same energy reduced to a bar of
piecewise-constant section, E = ∫ [A ψ(λ) − A Br λ B(z)/μ0 + ρ A g z] dZ, whose Euler–Lagrange equation puts the
magnetic pull only where the section changes (magnetic charge on the end face and on each step, Br·ΔA·B/μ0) and the
weight everywhere; λ(σ) is the solver's Neo-Hookean (K = 20 G) under uniaxial stress, B the textbook on-axis field of
the cylinder at the deformed positions (fixed-point iteration). It ignores how stress spreads between the thin necks
and the thick rings (each as long as it is wide): an estimate, not a reference to the per cent. (For a uniform bar
the same reduction is asserted within 3 % in test_mpm_scene, AMagnetsPullStretchesABarAsTheOneDimensionalEnergyPredicts.)

    /usr/bin/python3 tools/mpm_extension_sweep.py --out runs/extension_sweep \\
        --figure docs/figures/mpm_extension_sweep.png --csv docs/figures/mpm_extension_sweep.csv

A missing or malformed input gives one line on stderr, exit status 2 and no CSV or PNG. The robot's geometry (its
free end at 30 mm, used for the gap) and the 1D bar's sections are the bundled scene's; another scene is refused.
"""
import argparse
import csv
import functools
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tool_errors import input_error  # noqa: E402
try:  # a run's probes.csv as (t_s, tip_z_mm), exit 2 when malformed; it loads matplotlib too
    from plot_mpm_sweeps import run_mpm, tip_track  # noqa: E402
except ImportError as e:
    print(f"mpm_extension_sweep: matplotlib: {e}", file=sys.stderr)
    sys.exit(2)

TIP_Z = 30.0  # the bundled robot's free end [mm]
MAGNET_LENGTH = 100.0  # the bundled magnet's length [mm]


MU0 = 4e-7 * math.pi
# The bundled robot (mm): sections from its free end up to the clamp's lower face, and its material and magnet.
SECTIONS = [(30, 36, 5.0), (36, 42, 2.5), (42, 48, 5.0), (48, 54, 2.5), (54, 60, 5.0), (60, 66, 2.5), (66, 72, 5.0)]
SHEAR, BULK, DENSITY, REMANENCE = 33000.0, 20 * 33000.0, 1840.0, 0.101
MAGNET_RADIUS, POLARISATION = 50.0, 1.44


def cylinder_axis_field(z, centre, radius, length, polarisation):
    """B_z [T] on the axis of a uniformly magnetised cylinder (axial polarisation J [T]) at height z (all in m)."""
    u = z - centre
    top, bottom = u + 0.5 * length, u - 0.5 * length
    return 0.5 * polarisation * (top / math.hypot(top, radius) - bottom / math.hypot(bottom, radius))


def _nominal_stresses(lam, mu):
    """(P_zz, P_xx) [Pa] of the solver's Neo-Hookean, P = G J^(-2/3) (F - I1/3 F^-T) + K J (J - 1) F^-T, at
    F = diag(mu, mu, lam)."""
    j = mu * mu * lam
    i1 = 2 * mu * mu + lam * lam
    g = SHEAR * j ** (-2.0 / 3.0)
    return (g * (lam - i1 / 3.0 / lam) + BULK * j * (j - 1.0) / lam,
            g * (mu - i1 / 3.0 / mu) + BULK * j * (j - 1.0) / mu)


def _uniaxial_table(lowest=0.5, highest=6.0, points=4000):
    """(axial stretches, nominal stresses) under uniaxial stress, the sides free: for each axial stretch the lateral
    one with P_xx = 0, by bisection (P_xx rises with it)."""
    lams, sigmas = [], []
    for k in range(points):
        lam = lowest + (highest - lowest) * k / (points - 1)
        lo, hi = 1e-3, 10.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if _nominal_stresses(lam, mid)[1] > 0.0:
                hi = mid
            else:
                lo = mid
        lams.append(lam)
        sigmas.append(_nominal_stresses(lam, 0.5 * (lo + hi))[0])
    return lams, sigmas


_TABLE = []


def uniaxial_stretch(sigma):
    """Axial stretch under a uniaxial nominal stress sigma [Pa] (interpolated in the table; None beyond λ = 6)."""
    if not _TABLE:
        _TABLE.extend(_uniaxial_table())
    lams, sigmas = _TABLE
    if not sigmas[0] <= sigma <= sigmas[-1]:
        return None
    lo, hi = 0, len(sigmas) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if sigmas[mid] <= sigma:
            lo = mid
        else:
            hi = mid
    return lams[lo] + (sigma - sigmas[lo]) / (sigmas[hi] - sigmas[lo]) * (lams[hi] - lams[lo])


def one_dimensional_extension(distance_mm, gravity=9.81, per_mm=20, passes=200):
    """The 1D bar's extension [mm] with the magnet's top face distance_mm below the free end, or None where the
    fixed-point iteration finds no equilibrium (the pull grows faster than the bar resists as it nears the magnet)."""
    centre = (TIP_Z - distance_mm - 0.5 * MAGNET_LENGTH) * 1e-3

    def field(z):
        return cylinder_axis_field(z, centre, MAGNET_RADIUS * 1e-3, MAGNET_LENGTH * 1e-3, POLARISATION)

    magnetisation = REMANENCE / MU0
    h = 1e-3 / per_mm  # layers of h: every section boundary falls between two layers
    layers = []  # (reference height of the midpoint [m], section area [m²]), from the free end up
    for a, b, r in SECTIONS:
        for k in range(int(round((b - a) * per_mm))):
            layers.append((a * 1e-3 + (k + 0.5) * h, math.pi * (r * 1e-3) ** 2))
    top = SECTIONS[-1][1] * 1e-3  # the clamp's lower face, fixed
    steps = [(SECTIONS[k][1] * 1e-3, math.pi * (SECTIONS[k + 1][2] ** 2 - SECTIONS[k][2] ** 2) * 1e-6)
             for k in range(len(SECTIONS) - 1)]  # (reference height, area gained going up)
    stretch = [1.0] * len(layers)

    def deformed(z_ref):
        return top - sum(lam * h for (z, _), lam in zip(layers, stretch) if z > z_ref)

    moved = 0.0
    for _ in range(passes):
        if deformed(SECTIONS[0][0] * 1e-3) <= (TIP_Z - distance_mm) * 1e-3:
            return None  # the free end has reached the magnet
        force = layers[0][1] * magnetisation * field(deformed(SECTIONS[0][0] * 1e-3))  # the end face's charge
        weight = 0.0
        passed = 0
        new = []
        for z, area in layers:
            while passed < len(steps) and steps[passed][0] < z:
                force += steps[passed][1] * magnetisation * field(deformed(steps[passed][0]))
                passed += 1
            lam = uniaxial_stretch((force + weight + DENSITY * gravity * area * 0.5 * h) / area)
            if lam is None:
                return None
            new.append(lam)
            weight += DENSITY * gravity * area * h
        stretch = new
        moved_next = sum((lam - 1.0) * h for lam in stretch)
        if abs(moved_next - moved) < 1e-9:
            return moved_next * 1e3
        moved = moved_next
    return None


fail = functools.partial(input_error, "mpm_extension_sweep")


def scene_text(template, distance_mm):
    """The bundled scene with its magnet placed so that its top face lies distance_mm below the robot's free end, the
    domain's floor 1 mm above that face and a second to settle in (None: not the bundled scene's lines)."""
    centre = TIP_Z - distance_mm - 0.5 * MAGNET_LENGTH
    text, n = re.subn(r"(polarisation: 1\.44, position: \[0, 0, )-?[0-9.]+\]", rf"\g<1>{centre:g}]", template)
    text, m = re.subn(r"domain: \{min: \[-12, -12, -?[0-9.]+\]", f"domain: {{min: [-12, -12, {TIP_Z - distance_mm + 1.0:g}]",
                      text)
    text, k = re.subn(r"duration: [0-9.]+", "duration: 1.0", text)
    return text if n == 1 and m == 1 and k == 1 else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="assets/scenes/mpm_gradient_extension.yaml")
    ap.add_argument("--magvine", default="build/src/cli/magvine")
    ap.add_argument("--distances", default="30,40,50,55,60,70,80,100,120",
                    help="gaps to the magnet's top face [mm] (the default: docs/figures/mpm_extension_sweep.csv)")
    ap.add_argument("--out", required=True, help="folder for the scenes and runs")
    ap.add_argument("--csv", help="the table (default OUT/extension_sweep.csv)")
    ap.add_argument("--figure", help="the PNG (default OUT/extension_sweep.png)")
    a = ap.parse_args()
    try:
        template = open(a.scene, encoding="utf-8").read()
    except OSError as e:
        fail(a.scene, e.strerror)
    try:
        distances = [float(d) for d in a.distances.split(",")]
    except ValueError:
        fail("--distances", "not a comma-separated list of numbers")
    if not distances or not all(math.isfinite(d) and d >= 5.0 for d in distances):
        fail("--distances", "each gap must be at least 5 mm (the domain's floor, 1 mm above the magnet, lies below "
                            "the robot's free end)")
    if scene_text(template, distances[0]) is None:
        fail(a.scene, "no magnet 'polarisation: 1.44, position: [0, 0, z]', domain or duration line (not the "
                      "bundled scene?)")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:
        fail("matplotlib", str(e))
    out_csv = a.csv or os.path.join(a.out, "extension_sweep.csv")
    out_png = a.figure or os.path.join(a.out, "extension_sweep.png")
    for path in (a.csv, a.figure):
        if path and not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            fail(path, "its folder does not exist")
    if not (os.path.isfile(a.magvine) and os.access(a.magvine, os.X_OK)):
        fail(a.magvine, "not an executable (--magvine)")
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for d in distances:
        text = scene_text(template, d)
        scene = os.path.join(a.out, f"extension_{d:g}mm.yaml")
        run = os.path.join(a.out, f"run_{d:g}mm")
        with open(scene, "w", encoding="utf-8") as f:
            f.write(text)
        print(f"mpm_extension_sweep: {d:g} mm ...", file=sys.stderr, flush=True)
        wall = run_mpm(a.magvine, scene, run, "mpm_extension_sweep")
        times, heights = tip_track(run)
        first, last, t_end = heights[0], heights[-1], times[-1]
        # Within three cells of the floor above the magnet: pulled down onto it (no equilibrium in between).
        onto = last - (TIP_Z - d + 1.0) < 3.0
        estimate = one_dimensional_extension(d)
        rows.append({"distance_mm": d, "extension_mm": first - last, "onto_magnet": int(onto),
                     "estimate_1d_mm": "" if estimate is None else estimate, "settled_at_s": t_end, "runtime_s": wall})
    with open(out_csv, "w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})

    fig, ax = plt.subplots(figsize=(6, 4.2))
    ds = [r["distance_mm"] for r in rows]
    held = [r for r in rows if not r["onto_magnet"]]
    ax.plot([r["distance_mm"] for r in held], [r["extension_mm"] for r in held], "o-",
            label="MPM (3D, 1 mm cells), settled")
    estimated = [r for r in rows if r["estimate_1d_mm"] != ""]
    ax.plot([r["distance_mm"] for r in estimated], [r["estimate_1d_mm"] for r in estimated], "s--", color="C2",
            label="1D bar of stepped section (estimate)")
    onto = [r for r in rows if r["onto_magnet"]]
    if onto:
        ax.plot([r["distance_mm"] for r in onto], [r["extension_mm"] for r in onto], "x", color="C3", markersize=9,
                label="pulled onto the magnet")
    ax.set_xlabel("gap between the robot's free end and the magnet [mm]")
    ax.set_ylabel("extension [mm]")
    ax.set_title("Gradient extension towards the magnet (thesis 3.6.3, fig 3.5)")
    ax.invert_xaxis()
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    for r in rows:
        print(f"{r['distance_mm']:5.1f} mm: extension {r['extension_mm']:.3f} mm"
              f"{' (pulled onto the magnet)' if r['onto_magnet'] else ''}, 1D "
              f"{'none' if r['estimate_1d_mm'] == '' else format(r['estimate_1d_mm'], '.3f')}, ended at {r['settled_at_s']:.3f} s, "
              f"{r['runtime_s']:.0f} s")
    print(f"mpm_extension_sweep: {out_csv}, {out_png}", file=sys.stderr)


if __name__ == "__main__":
    main()
