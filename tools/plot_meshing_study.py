#!/usr/bin/env python3
"""Plot the phantom meshing study written by `magvine study phantom-meshing --out DIR`.

Left: error against meshing time for a capsule lumen (relative volume and area error, worst vertex distance from the
exact surface relative to the radius) and for the default bronchial tree (relative volume change against the finest
spacing). Right: the same errors against the grid spacing, with the h^2 slope.

Usage: /usr/bin/python3 tools/plot_meshing_study.py DIR [--out DIR/meshing_study.png]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

CAPSULE_RADIUS_M = 6e-3  # the study's capsule (src/scene/src/meshing_study.cpp)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    args = ap.parse_args()
    path = os.path.join(args.dir, "meshing_study.csv")
    out = args.out or os.path.join(args.dir, "meshing_study.png")
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        cap = [r for r in rows if r["case"] == "capsule"]
        tree = [r for r in rows if r["case"] == "bronchial_tree"]
        col = lambda rs, k: [float(r[k]) for r in rs]  # noqa: E731
        series = [
            ("capsule volume", cap, col(cap, "volume_rel_err"), "o-", "tab:blue"),
            ("capsule area", cap, col(cap, "area_rel_err"), "s-", "tab:green"),
            ("capsule surface (max |d| / r)", cap, [e / CAPSULE_RADIUS_M for e in col(cap, "max_surface_err_m")],
             "^-", "tab:purple"),
            ("bronchial tree volume (vs 0.22 mm)", tree, col(tree, "volume_rel_err"), "D-", "tab:red"),
        ]
    except OSError as e:
        print(f"{path}: {e.strerror}", file=sys.stderr)
        return 2
    except (KeyError, ValueError) as e:
        print(f"{path}: malformed study CSV ({e})", file=sys.stderr)
        return 2

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for label, rs, err, style, color in series:
        a.loglog(col(rs, "seconds"), err, style, color=color, label=label)
        b.loglog([1e3 * h for h in col(rs, "spacing_m")], err, style, color=color, label=label)
    h = [1e3 * x for x in col(cap, "spacing_m")]
    ref = col(cap, "volume_rel_err")
    b.loglog(h, [ref[0] * (x / h[0]) ** 2 for x in h], "k:", label="slope h²")
    b.axvline(0.4, color="gray", lw=0.8, ls="--")
    b.annotate("default 0.4 mm", (0.4, b.get_ylim()[0]), xytext=(3, 3), textcoords="offset points", fontsize=8)
    a.set_xlabel("meshing time [s] (one core)")
    a.set_ylabel("relative error")
    a.set_title("Error against runtime")
    b.set_xlabel("grid spacing h [mm]")
    b.set_title("Error against spacing")
    for ax in (a, b):
        ax.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    fig.savefig(out, dpi=120)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
