#!/usr/bin/env python3
"""Plot the growth resolution study written by `magvine study growth --out DIR`.

One column per knob (edge length h, time step dt, barrier distance d-hat), one colour per case (past the carina,
into a daughter of the Y): top, the tip path's largest distance from the finest run's at equal grown length,
against the run's time; bottom, the relative errors of the peak total wall normal force and of the peak force on a
node against the same finest run. Failed runs are named in the title of their column.

Usage: /usr/bin/python3 tools/plot_growth_study.py DIR [--out DIR/growth_study.png]
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

KNOBS = (("edge_length", "edge length h", 1e3, "mm"), ("dt", "time step dt", 1e3, "ms"),
         ("contact_distance", "barrier distance d̂", 1e3, "mm"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    args = ap.parse_args()
    path = os.path.join(args.dir, "growth_study.csv")
    out = args.out or os.path.join(args.dir, "growth_study.png")
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        for r in rows:
            for k in ("value", "ok", "seconds", "tip_path_error_m", "peak_node_normal_rel_err",
                      "peak_total_normal_rel_err"):
                r[k] = float(r[k])
    except OSError as e:
        print(f"{path}: {e.strerror}", file=sys.stderr)
        return 2
    except (KeyError, ValueError) as e:
        print(f"{path}: malformed study CSV ({e})", file=sys.stderr)
        return 2
    if not rows:
        print(f"{path}: no runs", file=sys.stderr)
        return 2

    fig, axes = plt.subplots(2, 3, figsize=(13, 7), constrained_layout=True)
    cases = sorted({r["case"] for r in rows}, key=lambda c: (c != "carina", c))
    colours = {"carina": "tab:blue", "y": "tab:red"}
    for col, (knob, name, scale, unit) in enumerate(KNOBS):
        top, bottom = axes[0][col], axes[1][col]
        notes = []
        for case in cases:
            rs = [r for r in rows if r["knob"] == knob and r["case"] == case]
            if not rs:
                continue
            colour = colours.get(case, "tab:gray")
            ref = rs[-1]
            notes.append(f"{case}: vs {scale * ref['value']:.3g} {unit} ({ref['seconds']:.2f} s)")
            failed = [f"{scale * r['value']:.3g}" for r in rs if r["ok"] == 0]
            if failed:
                notes.append(f"{case} failed: {', '.join(failed)} {unit}")
            good = [r for r in rs[:-1] if r["ok"] == 1 and not math.isnan(r["tip_path_error_m"])]
            if not good:
                continue
            t = [r["seconds"] for r in good]
            top.plot(t, [1e3 * r["tip_path_error_m"] for r in good], "o-", color=colour, label=case)
            for r in good:
                top.annotate(f"{scale * r['value']:.3g}", (r["seconds"], 1e3 * r["tip_path_error_m"]),
                             xytext=(3, 3), textcoords="offset points", fontsize=7, color=colour)
            bottom.plot(t, [100 * r["peak_total_normal_rel_err"] for r in good], "^-", color=colour,
                        label=f"{case}: peak total normal force")
            bottom.plot(t, [100 * r["peak_node_normal_rel_err"] for r in good], "s--", color=colour, alpha=0.6,
                        label=f"{case}: peak force on a node")
        top.set_title(f"{name} [{unit}]\n" + "; ".join(notes), fontsize=8)
        top.set_ylabel("tip path error [mm]")
        bottom.set_ylabel("relative error [%]")
        bottom.set_xlabel("run time [s] (one core)")
        top.legend(fontsize=8)
        bottom.legend(fontsize=7)
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    fig.suptitle("Vine growth in anatomy (Ø5 mm fluid vine, 100 mm): error against run time, each knob against "
                 "its finest run", fontsize=11)
    fig.savefig(out, dpi=130)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
