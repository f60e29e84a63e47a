#!/usr/bin/python3
"""Held or aimed: what each pushed needle of the CT case study (tools/ct_case_study.py) did, against the room the
vine had in its lumen at the stop.

    /usr/bin/python3 tools/plot_biopsy_hold.py STUDY_DIR [STUDY_DIR ...] --out FILE.png [--csv FILE.csv]

Each STUDY_DIR is a case study's output (its scenes/ and <case>/runs/*/metrics.json, written with --keep-runs as
the tool does). For every run whose needle was pushed: the clearance (the stop's lumen diameter from the plan less
the vine's diameter from the scene), the largest needle force the vine held (`held_reaction_N`: at an equilibrium
within the slide limit; filled where it held the whole puncture, open where its tip then slid back past the limit)
and the tip's angle to the nodule after aiming (the held panels leave out needles that never met the tissue); and
the force held against the run's largest contact pressure over the scene's (nominal) pressure (a pressurised film
presses a flat patch at its own pressure: far above it, the contact model's rigid sphere carries the load). Three
panels side by side, one colour per vine diameter; --csv writes the points. A missing input gives one line on stderr
and exit status 2.
"""
import argparse
import csv
import functools
import glob
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tool_errors import input_error  # noqa: E402

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


fail = functools.partial(input_error, "plot_biopsy_hold")


def scene_value(path, key):
    """robot.<key> of a case-study scene (the tool writes it as "  key: number"; units mm and kPa)."""
    try:
        with open(path) as f:
            m = re.search(r"^  " + key + r":\s*([0-9.]+)\s*$", f.read(), re.MULTILINE)
    except OSError:
        fail(path, "cannot read the case's scene")
    if not m:
        fail(path, f"no robot {key} in the scene")
    return float(m.group(1))


def contact_pressure(m, path):
    """The run's largest contact pressure [Pa] from its metrics.json."""
    value = m.get("max_contact_pressure_Pa")
    if not isinstance(value, (int, float)):
        fail(path, "no max_contact_pressure_Pa")
    return value


def points(study):
    """One row per pushed needle of a study: case, repeat, vine and lumen diameters [mm], force [N], held, angle."""
    scenes = os.path.join(study, "scenes")
    if not os.path.isdir(scenes):
        fail(study, "not a case study's output (no scenes/)")
    rows = []
    for metrics in sorted(glob.glob(os.path.join(study, "*", "runs", "*", "metrics.json"))):
        case = metrics.split(os.sep)[-4]
        try:
            with open(metrics) as f:
                m = json.load(f)
            b = m.get("biopsy") or {}
        except (OSError, ValueError) as e:
            fail(metrics, f"unreadable ({e})")
        if not b.get("needle_pushed"):
            continue
        if b.get("stop_lumen_diameter_m") is None or b.get("held_reaction_N") is None:
            fail(metrics, "no biopsy.stop_lumen_diameter_m or held_reaction_N (written by magvine since 2026-12-06: "
                          "run the study again)")
        scene = os.path.join(scenes, case + ".yaml")
        vine = scene_value(scene, "diameter")
        rows.append({"case": case, "run": metrics.split(os.sep)[-2], "vine_mm": vine,
                     "lumen_mm": round(1e3 * b["stop_lumen_diameter_m"], 3),
                     "clearance_mm": round(1e3 * b["stop_lumen_diameter_m"] - vine, 3),
                     "held_N": b["held_reaction_N"], "held_all": bool(b.get("held")),
                     "met_tissue": (b.get("max_reaction_N") or 0.0) > 0.0,
                     "aim_angle_deg": b.get("aim_angle_deg"),
                     "film_kPa": scene_value(scene, "pressure"),
                     "contact_kPa": round(1e-3 * contact_pressure(m, metrics), 3)})
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("studies", nargs="+")
    p.add_argument("--out", required=True)
    p.add_argument("--csv", default="")
    a = p.parse_args()
    rows = [r for s in a.studies for r in points(s)]
    if not rows:
        fail(" ".join(a.studies), "no pushed needle in these studies")
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(15, 4))
    colours = {}
    for r in rows:
        c = colours.setdefault(r["vine_mm"], f"C{len(colours)}")
        label = f"Ø{r['vine_mm']:g} mm vine"
        face = c if r["held_all"] and r["met_tissue"] else "none"
        if r["met_tissue"]:  # a needle that never met the tissue (aimed away) held nothing to speak of
            left.scatter(r["clearance_mm"], r["held_N"], edgecolors=c, facecolors=face, s=36, label=label)
            middle.scatter(r["contact_kPa"] / r["film_kPa"], r["held_N"], edgecolors=c, facecolors=face, s=36,
                           label=label)
        if r["aim_angle_deg"] is not None:
            right.scatter(r["clearance_mm"], r["aim_angle_deg"], edgecolors=c, facecolors=face, s=36, label=label)
    left.axhline(1.0, color="grey", lw=0.8, ls="--")
    left.text(left.get_xlim()[1], 1.0, "needle's 1 N ", ha="right", va="bottom", fontsize=8, color="grey")
    left.set_xlabel("lumen Ø at the stop − vine Ø [mm]")
    left.set_ylabel("largest needle force held [N]")
    left.set_title("held (filled: the whole puncture; open: slid back)", fontsize=9)
    middle.axhline(1.0, color="grey", lw=0.8, ls="--")
    middle.axvline(1.0, color="grey", lw=0.8, ls=":")
    middle.set_xscale("log")
    middle.set_xlabel("the run's largest contact pressure / the scene's pressure")
    middle.set_ylabel("largest needle force held [N]")
    middle.set_title("a film presses at most its own pressure (dotted)", fontsize=9)
    right.set_xlabel("lumen Ø at the stop − vine Ø [mm]")
    right.set_ylabel("tip's angle to the nodule after aiming [deg]")
    right.set_title("aimed (0°: the needle leaves towards the nodule)", fontsize=9)
    for ax in (left, middle, right):
        handles, labels = ax.get_legend_handles_labels()
        unique = dict(zip(labels, handles))
        ax.legend(unique.values(), unique.keys(), fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    print(f"plot_biopsy_hold: {len(rows)} needles -> {a.out}")


if __name__ == "__main__":
    main()
