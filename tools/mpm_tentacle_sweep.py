#!/usr/bin/python3
"""Pittiglio's continuum robot (thesis 3.6.5.1) over a field sweep: MPM's settled tip beside a planar elastica.

The robot of assets/scenes/mpm_tentacle.yaml (alternating magnetic and non-magnetic Ø4 mm sections hanging from a
clamp) is run with each magnetisation profile, "a" (the scene's) and "b" (PROFILE_B below, the thesis's public
code's tentacleF), at each field of the sweep (uniform, along +x, ramped over 0.1 s), until `magvine mpm` finds it
at rest. The thesis set its simulation against the fabricated robots (mean tip error over its sweep 0.38 mm with
profile a, 6.97 mm with b); their measured tips are not published, so the reference here is a second method on the
same model: the planar Kirchhoff elastica of the scene's sections (inextensible and unshearable, EI = E·πr⁴/4 with
the MPM material's small-strain E = 9KG/(3K + G), K = 20 G; weight ρAg; a magnetic couple per length
A (B̃r/μ0) × B with B̃r turning with the section), clamped at the clamp's lower face, discretised in 1600 segments and
solved by Newton to round-off (the tip moves ≤ 1.5e-4 mm from 800 to 1600 segments). Every magnetisation direction
lies in the x–z plane and so does the field, so the elastica is planar.

A planar state is a reference only while it is stable: a section magnetised against the field can turn about its own
axis. For each point the tool also gives the lowest eigenvalue of the energy's second variation in twist at the
elastica's equilibrium (twist_stiffness; negative: the planar state is unstable) and the largest twist the MPM body
took about its axis (largest_twist, from its first and last particle snapshots); the mean tip gap is taken over the
fields below the first at which the planar path loses that stability (twist_threshold, on a 0.25 mT grid; beyond
it the body has left the plane, even where a planar state at a larger field is stable again).

    /usr/bin/python3 tools/mpm_tentacle_sweep.py --out runs/tentacle_sweep \\
        --figure docs/figures/mpm_tentacle_sweep.png --csv docs/figures/mpm_tentacle_sweep.csv

A missing or malformed input gives one line on stderr, exit status 2 and no CSV or PNG.
"""
import argparse
import copy
import csv
import functools
import json
import math
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tool_errors import input_error  # noqa: E402

MU0 = 4e-7 * math.pi
# Profile b: the magnetic sections' directions (x, y, z) in the thesis's public code (tentacleF).
PROFILE_B = {"s2": [-0.81, 0, -0.59], "s4": [-0.26, 0, 0.97], "s6": [-0.77, 0, 0.64], "s8": [-0.94, 0, -0.35]}


fail = functools.partial(input_error, "mpm_tentacle_sweep")


def robot_sections(scene, path):
    """The scene's sections below the clamp, from it down: (from, to) [m of arc], G [Pa], ρ, radius [m], B̃r [T],
    direction (x, z) or None. Exits 2 unless the scene is a vertical chain of touching cylinders on the z axis under
    one clamp, in mm and Pa, each of K = 20 G (the elastica's material), with at least one magnetised."""
    try:
        units = scene.get("units", {})
        if units.get("length") != "mm" or units.get("pressure", "Pa") != "Pa":
            fail(path, "units: the sweep reads lengths in mm and moduli in Pa (units: {length: mm})")
        bodies = scene["bodies"]
        clamp = scene["clamps"][0]
        face = float(clamp["min"][2])
        out = []
        for b in bodies:
            top, bottom = float(b["from"][2]), float(b["to"][2])
            if b["shape"] != "cylinder" or b["from"][:2] != [0, 0] or b["to"][:2] != [0, 0] or bottom >= top:
                fail(path, f"bodies: {b.get('name')}: not a cylinder down the z axis (not the bundled robot?)")
            m = b.get("magnetisation")
            direction = None
            remanence = 0.0
            if m:
                d = [float(v) for v in m["direction"]]
                if abs(d[1]) > 1e-12:
                    fail(path, f"bodies: {b['name']}: magnetisation out of the x-z plane (the elastica is planar)")
                if not math.hypot(d[0], d[2]) > 0.0:
                    fail(path, f"bodies: {b['name']}: magnetisation direction is zero")
                direction = (d[0], d[2])
                remanence = float(m["remanence"])
            shear, density = float(b["material"]["shear_modulus"]), float(b["material"]["density"])
            radius = float(b["radius"])
            bulk = float(b["material"].get("bulk_modulus", 20.0 * shear))
            if not (shear > 0.0 and density >= 0.0 and radius > 0.0) or abs(bulk / shear - 20.0) > 1e-9:
                fail(path, f"bodies: {b['name']}: needs shear_modulus > 0, density >= 0, radius > 0 and the "
                           "default bulk_modulus (K = 20 G)")
            a, c = max(0.0, face - top), face - bottom
            if c > 0.0:
                if abs(a * 1e-3 - (out[-1][1] if out else 0.0)) > 1e-9:
                    fail(path, f"bodies: {b['name']}: does not start where the body above it ends (sections must "
                               "touch, from the clamp down)")
                out.append((a * 1e-3, c * 1e-3, shear, density, radius * 1e-3, remanence, direction))
        if not out or not any(sec[6] is not None for sec in out):
            fail(path, "bodies: no section below the clamp, or none magnetised")
        return out
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as e:
        fail(path, f"not the bundled robot's form ({e!r})")


def elastica(sections, field, gravity=9.81, n=1600):
    """The clamped planar elastica of `sections` hanging along −z under gravity and a uniform field (Bx, Bz) [T]:
    the arc s [m] of each segment's midpoint, its (x, z) offset from the clamp [m] and its angle φ. Segment j has
    angle φ_j from the vertical, tangent (−sin φ, −cos φ); the energy Σ ½ k_j (φ_j − φ_{j−1})² − Σ ds m_j(φ_j)·B −
    Σ ds W_j cos φ_j (k the joints' EI/ds, harmonic mean across a section boundary; W_j the weight below segment j's
    midpoint) is minimised from straight by Newton (its Hessian is tridiagonal; shifted until Cholesky accepts it
    where it is not positive definite) with a backtracking line search. Raises RuntimeError when Newton does not
    converge in 500 steps."""
    import numpy as np

    length = sections[-1][1]
    ds = length / n
    s_mid = (np.arange(n) + 0.5) * ds
    ei, w, mx, mz = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    for a, b, shear, rho, r, remanence, direction in sections:
        sel = (s_mid >= a) & (s_mid < b)
        bulk = 20.0 * shear
        young = 9.0 * bulk * shear / (3.0 * bulk + shear)
        ei[sel] = young * math.pi * r ** 4 / 4.0
        w[sel] = rho * math.pi * r * r * gravity * ds
        if direction is not None:
            moment = remanence / MU0 * math.pi * r * r / math.hypot(*direction)  # per length [A·m]
            mx[sel], mz[sel] = moment * direction[0], moment * direction[1]
    if not (ei > 0).all():
        raise RuntimeError("a gap between the sections")
    weight_below = np.cumsum(w[::-1])[::-1] - 0.5 * w
    k = np.empty(n)
    k[0] = ei[0] / (0.5 * ds)  # the clamp to the first midpoint
    k[1:] = 2.0 / (1.0 / ei[:-1] + 1.0 / ei[1:]) / ds
    bx, bz = field

    def energy(phi):
        d = np.diff(phi, prepend=0.0)
        c, s = np.cos(phi), np.sin(phi)
        return (0.5 * np.sum(k * d * d) - ds * np.sum(bx * (mx * c + mz * s) + bz * (mz * c - mx * s))
                - ds * np.sum(weight_below * c))

    phi = np.zeros(n)
    for _ in range(500):
        d = np.diff(phi, prepend=0.0)
        c, s = np.cos(phi), np.sin(phi)
        grad = k * d
        grad[:-1] -= k[1:] * d[1:]
        grad += -ds * (bx * (mz * c - mx * s) - bz * (mx * c + mz * s)) + ds * weight_below * s
        diag = k + np.append(k[1:], 0.0) - ds * (-bx * (mx * c + mz * s) + bz * (mx * s - mz * c)) \
            + ds * weight_below * c
        off = -k[1:]
        h = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
        shift = 0.0
        while True:
            try:
                lower = np.linalg.cholesky(h + shift * np.eye(n))
                break
            except np.linalg.LinAlgError:
                shift = max(1e-9 * np.abs(diag).max(), 4.0 * shift)
        step = -np.linalg.solve(lower.T, np.linalg.solve(lower, grad))
        e0, t = energy(phi), 1.0
        while energy(phi + t * step) > e0 and t > 1e-12:
            t *= 0.5
        phi = phi + t * step
        if np.abs(t * step).max() < 1e-13 and shift == 0.0 and np.abs(grad).max() <= 1e-9 * np.abs(diag).max():
            break
    else:
        raise RuntimeError("the elastica's Newton did not converge in 500 steps")
    x = np.cumsum(-np.sin(phi)) * ds - 0.5 * ds * -np.sin(phi)
    z = np.cumsum(-np.cos(phi)) * ds - 0.5 * ds * -np.cos(phi)
    return s_mid, x, z, phi


def at_arc(s_mid, x, z, s):
    """(x, z) of the elastica at arc s, interpolated between midpoints."""
    import numpy as np
    return float(np.interp(s, s_mid, x)), float(np.interp(s, s_mid, z))


def twist_threshold(sections, top, step=0.25e-3, n=400):
    """The lowest field along +x [T], on a grid of `step` up to `top`, at which the planar state loses its stability in
    twist (twist_stiffness < 0), or None: beyond it the loading path leaves the plane, even where a planar state at a
    larger field is stable again."""
    k = 1
    while k * step <= top + 1e-12:
        if twist_stiffness(sections, (k * step, 0.0), n=n) < 0.0:
            return k * step
        k += 1
    return None


def twist_stiffness(sections, field, gravity=9.81, n=800):
    """The lowest eigenvalue [N·m] of the second variation of the energy in a twist ψ(s) of each section about its
    own tangent, at the planar elastica's equilibrium: ½ Σ GJ ψ'² + ½ Σ ds (m⊥·B) ψ² (GJ = G·πr⁴/2; m⊥ the
    magnetic moment per length across the tangent; a twist turns m⊥ about t, and at a planar state the first-order
    term (t × m⊥)·B vanishes); its value scales with the segments, its sign is what counts. Negative: the planar
    state is unstable and the body twists out of the x–z plane,
    where the planar elastica no longer describes it (a section magnetised against the field turns about its axis).
    Twist alone; its coupling with bending out of the plane could only lower the eigenvalue."""
    import numpy as np

    s_mid, _, _, phi = elastica(sections, field, gravity, n)
    ds = sections[-1][1] / n
    gj, k = np.zeros(n), np.zeros(n)
    for a, b, shear, _, r, remanence, direction in sections:
        sel = (s_mid >= a) & (s_mid < b)
        gj[sel] = shear * math.pi * r ** 4 / 2.0
        if direction is not None:
            moment = remanence / MU0 * math.pi * r * r / math.hypot(*direction)
            c, s = np.cos(phi[sel]), np.sin(phi[sel])
            mx = moment * (direction[0] * c + direction[1] * s)
            mz = moment * (direction[1] * c - direction[0] * s)
            tx, tz = -s, -c
            along = mx * tx + mz * tz
            k[sel] = ds * ((mx - along * tx) * field[0] + (mz - along * tz) * field[1])
    joint = np.empty(n)
    joint[0] = gj[0] / (0.5 * ds)
    joint[1:] = 2.0 / (1.0 / gj[:-1] + 1.0 / gj[1:]) / ds
    h = np.diag(joint + np.append(joint[1:], 0.0) + k) + np.diag(-joint[1:], 1) + np.diag(-joint[1:], -1)
    return float(np.linalg.eigvalsh(h)[0])


def snapshot(path):
    """A PLY snapshot's particle positions (N × 3) [mm] (ASCII, as magvine mpm writes it)."""
    import numpy as np
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.strip() == "end_header":
                break
        return np.loadtxt(f, usecols=(0, 1, 2), ndmin=2)


def largest_twist(run, clamp_face, length, slab=2.0, every=5.0):
    """The largest twist [degrees] of the MPM body about its own axis between its first and last snapshots: for each
    slab of particles (`slab` mm thick, every `every` mm below the clamp) the best rotation of its particles about
    their centroid (Kabsch), less the swing that turns its axis (−z at rest) onto its new direction; the angle left,
    about the axis, folded into 0–180°. None without two snapshots."""
    import numpy as np
    folder = os.path.join(run, "snapshots")
    try:
        names = sorted(n for n in os.listdir(folder) if n.endswith(".ply"))
        if len(names) < 2:
            return None
        first, last = snapshot(os.path.join(folder, names[0])), snapshot(os.path.join(folder, names[-1]))
    except (OSError, ValueError):
        return None
    axis = np.array([0.0, 0.0, -1.0])
    worst = 0.0
    depth = every
    while depth < length:
        sel = np.abs(first[:, 2] - (clamp_face - depth)) < 0.5 * slab
        depth += every
        if sel.sum() < 4:
            continue
        p0 = first[sel] - first[sel].mean(axis=0)
        p1 = last[sel] - last[sel].mean(axis=0)
        u, _, vt = np.linalg.svd(p0.T @ p1)
        d = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
        rotation = vt.T @ d @ u.T  # p1 ≈ rotation · p0
        turned = rotation @ axis
        v, c = np.cross(turned, axis), float(turned @ axis)
        vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
        back = (np.eye(3) + vx + vx @ vx / (1.0 + c)) @ rotation  # what is left: a turn about the axis
        worst = max(worst, abs(math.degrees(math.atan2(back[1, 0], back[0, 0]))))
    return worst


def final_probe(run):
    """The run's tip probe: its first and last (x, y, z) [mm], and the time of the last [s]."""
    path = os.path.join(run, "probes.csv")
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        keys = ("tip_x_mm", "tip_y_mm", "tip_z_mm")
        if not rows or any(k not in rows[0] for k in keys + ("t_s",)):
            fail(path, "no t_s, tip_x_mm, tip_y_mm, tip_z_mm columns")
        return [float(rows[0][k]) for k in keys], [float(rows[-1][k]) for k in keys], float(rows[-1]["t_s"])
    except OSError as e:
        fail(path, e.strerror)
    except ValueError as e:
        fail(path, f"not a number ({e})")


def last_snapshot(run):
    """The last PLY snapshot's particle (x, z) [mm] (snapshot), or None."""
    folder = os.path.join(run, "snapshots")
    try:
        names = sorted(n for n in os.listdir(folder) if n.endswith(".ply"))
        if not names:
            return None
        points = snapshot(os.path.join(folder, names[-1]))
        return points[:, 0], points[:, 2]
    except (OSError, ValueError):
        return None


def rod_tip(magvine, folder, tag, sections, field, arc, sign):
    """magvine's Cosserat rod (`magvine run`, a free-space rod scene) of `sections`, all of one material, hanging
    from the clamp along −z in a field (Bx, Bz) [T]: its (x, y, z) [mm, from the clamp] at `arc` [m], or None where
    `magvine run` exits non-zero (exit 2 here if it leaves an unreadable shape.csv). The rod's torsion takes
    G = E/3 (magvine's rods), 1.6 % below the G of the MPM material's E. The rod twists as freely as it bends, so past the twist threshold it leaves the plane like the
    MPM body; a planar rod sits on the unstable branch there and its solve fails at the bifurcation, so each
    magnetisation is given a component of 0.1 % out of the plane, of sign `sign` (which picks the branch). Body
    frame: x the tangent (−z), y the base normal (+x), z = x × y (−y)."""
    import numpy as np

    _, _, shear, rho, radius, _, _ = sections[0]  # one material (--uniform-material)
    bulk = 20.0 * shear
    magnetisation = []
    for a, b, _, _, _, remanence, direction in sections:
        if direction is not None:
            wx, wz = direction
            magnetisation.append({"from": a * 1e3, "to": b * 1e3, "remanence": remanence,
                                  "direction": [-wz, wx, -sign * 1e-3 * math.hypot(wx, wz)]})
    scene = {"units": {"length": "mm"},
             "robot": {"kind": "rod", "length": sections[-1][1] * 1e3,
                       "section": {"shape": "circle", "diameter": 2e3 * radius},
                       "youngs_modulus": 9.0 * bulk * shear / (3.0 * bulk + shear), "density": rho,
                       "magnetisation": magnetisation,
                       "base": {"position": [0, 0, 0], "direction": [0, 0, -1], "normal": [1, 0, 0]},
                       "node_spacing": 0.5},
             "magnets": [{"kind": "uniform", "field": [field[0], 0.0, field[1]]}],
             "simulation": {"gravity": [0, 0, -9.81]}}
    import yaml
    path = os.path.join(folder, f"rod_{tag}.yaml")
    out = os.path.join(folder, f"rod_{tag}")
    with open(path, "w", encoding="utf-8") as f:
        yaml.safe_dump(scene, f, sort_keys=False)
    done = subprocess.run([magvine, "run", path, "--out", out], stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL)
    if done.returncode != 0:
        return None
    try:
        shape = np.loadtxt(os.path.join(out, "shape.csv"), delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as e:
        fail(os.path.join(out, "shape.csv"), str(e))
    return [float(np.interp(arc, shape[:, 0], shape[:, k])) * 1e3 for k in (1, 2, 3)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="assets/scenes/mpm_tentacle.yaml")
    ap.add_argument("--magvine", default="build/src/cli/magvine")
    ap.add_argument("--fields", default="1,2.5,5,10,15,20", help="field magnitudes along +x [mT]")
    ap.add_argument("--profiles", default="a,b", help="a (the scene's) and/or b")
    ap.add_argument("--out", required=True, help="folder for the scenes and runs")
    ap.add_argument("--reuse", action="store_true",
                    help="keep a run whose scene in OUT is unchanged and which ended well (a sweep resumed)")
    ap.add_argument("--uniform-material", action="store_true",
                    help="every section of the magnetic sections' material, and magvine's 3D Cosserat rod of it "
                         "beside MPM (a second method past the twist threshold; magvine's rods take one material)")
    ap.add_argument("--csv", help="the table (default OUT/tentacle_sweep.csv)")
    ap.add_argument("--figure", help="the PNG (default OUT/tentacle_sweep.png)")
    a = ap.parse_args()
    try:
        import yaml
        import numpy  # noqa: F401
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from plot_mpm_sweeps import run_mpm  # the sweeps' one way to run magvine mpm
    except ImportError as e:
        fail("python", str(e))
    try:
        with open(a.scene, encoding="utf-8") as f:
            scene = yaml.safe_load(f)
    except OSError as e:
        fail(a.scene, e.strerror)
    except yaml.YAMLError as e:
        fail(a.scene, f"not YAML ({str(e).splitlines()[0]})")
    try:
        fields = [float(v) for v in a.fields.split(",")]
    except ValueError:
        fail("--fields", "not a comma-separated list of numbers")
    if not fields or not all(math.isfinite(v) and 0.0 <= v <= 100.0 for v in fields):
        fail("--fields", "each field must be 0-100 mT")
    profiles = a.profiles.split(",")
    if not profiles or any(p not in ("a", "b") for p in profiles):
        fail("--profiles", "a comma-separated list of a and b")
    if not isinstance(scene, dict) or not isinstance(scene.get("bodies"), list):
        fail(a.scene, "bodies: missing (not the bundled robot?)")
    magnetised = {b.get("name") for b in scene["bodies"] if isinstance(b, dict) and isinstance(b.get("magnetisation"), dict)}
    if not set(PROFILE_B) <= magnetised:
        fail(a.scene, f"bodies: no magnetised bodies {sorted(PROFILE_B)} (not the bundled robot?)")
    field = scene.get("field")
    ramp = field.get("keyframes") if isinstance(field, dict) else None
    if not isinstance(ramp, list) or not ramp or not isinstance(ramp[-1], dict) or "t" not in ramp[-1]:
        fail(a.scene, "field: no keyframes (not the bundled robot?)")
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        fail(a.out, "exists and is not a folder (--out)")
    out_csv = a.csv or os.path.join(a.out, "tentacle_sweep.csv")
    out_png = a.figure or os.path.join(a.out, "tentacle_sweep.png")
    for path in (a.csv, a.figure):
        if path and not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            fail(path, "its folder does not exist")
    if not (os.path.isfile(a.magvine) and os.access(a.magvine, os.X_OK)):
        fail(a.magvine, "not an executable (--magvine)")

    # Every variant's robot is read, and its elastica's twist threshold found, before the first MPM run.
    plans = []
    for profile in profiles:
        variant = copy.deepcopy(scene)
        if profile == "b":
            for b in variant["bodies"]:
                if b.get("name") in PROFILE_B:
                    b["magnetisation"]["direction"] = PROFILE_B[b["name"]]
        if a.uniform_material:
            magnetic = next(b for b in variant["bodies"] if isinstance(b.get("magnetisation"), dict))
            for b in variant["bodies"]:
                b["material"] = copy.deepcopy(magnetic.get("material"))
        sections = robot_sections(variant, a.scene)
        try:
            threshold = twist_threshold(sections, max(fields) * 1e-3)
        except RuntimeError as e:
            fail(a.scene, f"profile {profile}: {e}")
        plans.append((profile, variant, sections, threshold))
    os.makedirs(a.out, exist_ok=True)

    rows, shapes = [], {}
    for profile, variant, sections, threshold in plans:
        for mt in fields:
            ramp = variant["field"]["keyframes"]
            variant["field"]["keyframes"] = [{"t": 0, "b": [0, 0, 0]}, {"t": ramp[-1]["t"], "b": [mt * 1e-3, 0, 0]}]
            tag = f"{'uniform_' if a.uniform_material else ''}{profile}_{mt:g}mT"
            path = os.path.join(a.out, f"tentacle_{tag}.yaml")
            run = os.path.join(a.out, f"run_{tag}")
            text = yaml.safe_dump(variant, sort_keys=False)
            reuse = False
            if a.reuse and os.path.isfile(os.path.join(run, "probes.csv")):
                try:
                    with open(path, encoding="utf-8") as f:
                        reuse = f.read() == text
                    with open(os.path.join(run, "metrics.json"), encoding="utf-8") as f:
                        metrics = json.load(f)
                    reuse = reuse and metrics.get("ok") is True
                    wall = float(metrics.get("runtime_s", float("nan")))
                except (OSError, ValueError, TypeError, AttributeError):
                    reuse = False
            if not reuse:
                with open(path, "w", encoding="utf-8") as f:
                    f.write(text)
                print(f"mpm_tentacle_sweep: profile {profile}, {mt:g} mT ...", file=sys.stderr, flush=True)
                wall = run_mpm(a.magvine, path, run, "mpm_tentacle_sweep")
            first, last, t_end = final_probe(run)
            face = float(variant["clamps"][0]["min"][2])
            arc = (face - first[2]) * 1e-3
            try:
                s_mid, ex, ez, _ = elastica(sections, (mt * 1e-3, 0.0))
                stiffness = twist_stiffness(sections, (mt * 1e-3, 0.0))
            except RuntimeError as e:
                fail(a.scene, f"profile {profile}, {mt:g} mT: {e}")
            rx, rz = at_arc(s_mid, ex, ez, arc)
            rx, rz = rx * 1e3, face + rz * 1e3
            error = math.hypot(last[0] - rx, last[2] - rz)
            twist = largest_twist(run, face, sections[-1][1] * 1e3)
            rows.append({"profile": profile, "field_mT": mt, "mpm_tip_x_mm": last[0], "mpm_tip_z_mm": last[2],
                         "mpm_tip_y_mm": last[1], "mpm_largest_twist_deg": "" if twist is None else twist,
                         "elastica_tip_x_mm": rx, "elastica_tip_z_mm": rz,
                         "planar_twist_eigenvalue": stiffness,
                         "twist_threshold_mT": "" if threshold is None else threshold * 1e3,
                         "planar_stable": int(threshold is None or mt * 1e-3 < threshold),
                         "tip_error_mm": error, "settled_at_s": t_end, "runtime_s": wall})
            if a.uniform_material:
                # The twisted branches are mirror images in y: the rod's is taken on the MPM body's side (or the
                # other sign where the first fails).
                tip = rod_tip(a.magvine, a.out, tag, sections, (mt * 1e-3, 0.0), arc, 1.0)
                if tip is None or (abs(last[1]) > 0.05 and tip[1] * last[1] < 0.0):
                    tip = rod_tip(a.magvine, a.out, tag, sections, (mt * 1e-3, 0.0), arc, -1.0) or tip
                rows[-1]["rod_tip_x_mm"] = "" if tip is None else tip[0]
                rows[-1]["rod_tip_y_mm"] = "" if tip is None else tip[1]
                rows[-1]["rod_tip_z_mm"] = "" if tip is None else face + tip[2]
                rows[-1]["rod_gap_mm"] = "" if tip is None else math.dist(last, (tip[0], tip[1], face + tip[2]))
                said = "its solve failed" if tip is None else f"{rows[-1]['rod_gap_mm']:.2f} mm from MPM's tip"
                print(f"  the Cosserat rod: {said}", file=sys.stderr, flush=True)
            shapes[(profile, mt)] = (ex * 1e3, face + ez * 1e3, last_snapshot(run))
            print(f"  profile {profile}, {mt:g} mT: MPM ({last[0]:.2f}, {last[2]:.2f}) mm, elastica ({rx:.2f}, {rz:.2f}) "
                  f"mm: {error:.2f} mm apart; planar path {'stable' if rows[-1]['planar_stable'] else 'unstable'} in twist, "
                  f"MPM twisted {twist if twist is not None else float('nan'):.0f}° (at rest at {t_end:.3f} s, "
                  f"{wall:.0f} s{', reused' if reuse else ''})", file=sys.stderr, flush=True)

    fig, axes = plt.subplots(1, len(profiles), figsize=(5.2 * len(profiles), 5.2), squeeze=False)
    for ax, profile in zip(axes[0], profiles):
        mine = [r for r in rows if r["profile"] == profile]
        for i, r in enumerate(mine):
            ex, ez, cloud = shapes[(profile, r["field_mT"])]
            colour = f"C{i}"
            if cloud is not None:
                ax.plot(cloud[0], cloud[1], ",", color=colour, alpha=0.15)
            twisted = r["mpm_largest_twist_deg"]
            state = "" if r["planar_stable"] else f", twists {twisted:.0f}°" if twisted != "" else ", twists"
            ax.plot(ex, ez, "-" if r["planar_stable"] else ":", color=colour, lw=1.2,
                    label=f"{r['field_mT']:g} mT: {r['tip_error_mm']:.2f} mm{state}")
            ax.plot(r["mpm_tip_x_mm"], r["mpm_tip_z_mm"], "o", color=colour, mfc="none")
        planar = [r["tip_error_mm"] for r in mine if r["planar_stable"]]
        thesis = {"a": 0.38, "b": 6.97}[profile]
        where = (f"mean tip gap {sum(planar) / len(planar):.2f} mm over the {len(planar)} planar "
                 f"field{'s' if len(planar) != 1 else ''}" if planar
                 else "no field keeps it planar")
        ax.set_title(f"profile {profile}: {where}\n(thesis, MPM against the robot: {thesis} mm)", fontsize=10)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("z [mm]")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, title="field along +x: tip gap", title_fontsize=8)
    fig.suptitle("Pittiglio's robot (thesis 3.6.5.1): MPM particles and tips (o) against the planar elastica (lines; "
                 "dotted where a twist makes it unstable)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    with open(out_csv, "w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.4g}" if k == "planar_twist_eigenvalue" else f"{v:.4f}" if isinstance(v, float)
                            else v) for k, v in r.items()})
    for profile in profiles:
        planar = [r["tip_error_mm"] for r in rows if r["profile"] == profile and r["planar_stable"]]
        print(f"profile {profile}: mean tip gap to the elastica {sum(planar) / len(planar):.3f} mm over the "
              f"{len(planar)} field(s) below the twist threshold" if planar
              else f"profile {profile}: no field below the twist threshold")
    print(f"mpm_tentacle_sweep: {out_csv}, {out_png}", file=sys.stderr)


if __name__ == "__main__":
    main()
