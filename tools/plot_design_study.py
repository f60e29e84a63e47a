#!/usr/bin/env python3
"""Plot the design study written by `magvine study design --out DIR`.

Top row: the best RMS so far against evaluations (equilibria solved) and against wall time, for the three methods
(least-squares, L-BFGS-B, Bayesian optimisation) on the S and the hook (thin lines: the four random starts) and on
the reachable targets (median over them); the thesis's 2 mm and the issue's 0.5 mm dashed. Bottom row: the S and the
hook, their targets and the least-squares designs' points from each start, in 3D.

Usage: /usr/bin/python3 tools/plot_design_study.py DIR [--out DIR/design_study.png]
"""
import argparse
import collections
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = {"least-squares": "tab:blue", "lbfgsb": "tab:orange", "bayesian": "tab:green"}
NAMES = {"least-squares": "Levenberg–Marquardt (exact Jacobian)", "lbfgsb": "L-BFGS-B (adjoint gradient)",
         "bayesian": "Bayesian optimisation (no gradient)"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    args = ap.parse_args()
    out = args.out or os.path.join(args.dir, "design_study.png")
    runs = collections.defaultdict(list)  # (target, method, seed) -> [(evaluation, time, best)]
    with open(os.path.join(args.dir, "design_history.csv")) as f:
        for r in csv.DictReader(f):
            runs[(r["target"], r["method"], r["start_seed"])].append(
                (int(r["evaluation"]), float(r["time_s"]), float(r["best_rms_m"]) * 1e3))
    shapes = collections.defaultdict(list)
    with open(os.path.join(args.dir, "design_shapes.csv")) as f:
        for r in csv.DictReader(f):
            shapes[(r["target"], r["start_seed"])].append(
                [float(r[k]) * 1e3 for k in ("target_x", "target_y", "target_z", "x", "y", "z")])

    fig = plt.figure(figsize=(15, 9))
    for col, target in enumerate(("S", "hook", "reachable")):
        for row, (index, label, scale) in enumerate(((0, "evaluations (equilibria solved)", "linear"),
                                                      (1, "wall time [s]", "log"))):
            ax = fig.add_subplot(3, 3, 1 + col + 3 * row)
            for method, colour in COLOURS.items():
                keys = [k for k in runs if k[1] == method and (k[0] == target or
                                                               (target == "reachable" and k[0].startswith("reachable")))]
                for n, k in enumerate(sorted(keys)):
                    xs = [p[index] for p in runs[k]]
                    ys = [p[2] for p in runs[k]]
                    ax.plot(xs, ys, color=colour, lw=0.8, alpha=0.6, label=NAMES[method] if n == 0 else None)
            ax.axhline(2.0, ls="--", color="grey", lw=0.8)
            ax.axhline(0.5, ls=":", color="grey", lw=0.8)
            ax.set_yscale("log")
            ax.set_xscale(scale)
            ax.set_xlabel(label)
            ax.set_ylabel("best RMS [mm]")
            ax.set_title({"S": "S (arbitrary)", "hook": "3D hook (arbitrary)", "reachable": "reachable targets"}[target])
            if col == 0 and row == 0:
                ax.legend(fontsize=7)
    for col, target in enumerate(("S", "hook")):
        ax = fig.add_subplot(3, 3, 7 + col, projection="3d")
        first = True
        for (t, seed), pts in sorted(shapes.items()):
            if t != target:
                continue
            if first:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], [p[2] for p in pts], "ko--", ms=4, label="target")
                first = False
            ax.plot([p[3] for p in pts], [p[4] for p in pts], [p[5] for p in pts], "-", marker=".",
                    label=f"design, start {seed}")
        # Equal scales on the three axes (a planar S would otherwise show its micrometres of z as a zigzag).
        every = [p for (t, _), pts in shapes.items() if t == target for p in pts]
        for axis, (lo_i, set_lim) in enumerate(((0, ax.set_xlim), (1, ax.set_ylim), (2, ax.set_zlim))):
            values = [p[lo_i] for p in every] + [p[lo_i + 3] for p in every]
            centre = 0.5 * (min(values) + max(values))
            span = max(max(p[i] for p in every) - min(p[i] for p in every) for i in range(3))
            set_lim(centre - 0.55 * span, centre + 0.55 * span)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_zlabel("z [mm]")
        ax.set_title(f"{target}: least-squares designs")
        ax.legend(fontsize=6)
    fig.suptitle("Design of thesis A.1.5.1's catheter (40 mm × Ø4 mm, 5 sections, 20 mT): best RMS against "
                 "evaluations and time")
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print(out)


if __name__ == "__main__":
    main()
