#!/usr/bin/python3
"""Plot the CT import study written by `magvine study ct-import --out DIR`.

Left: mean surface distance to the reference (in the map's voxels) against the import's time, one marker per
setting (level-set voxel, smoothing passes, adaptivity), one colour per case. Right: the volume error and the
triangle count against the same time. A missing or malformed input gives one line on stderr, exit status 2 and
no PNG.

    /usr/bin/python3 tools/plot_ct_study.py DIR [--out DIR/ct_study.png]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLUMNS = ("case", "voxel_factor", "smoothing", "adaptivity", "finest_voxel_m", "seconds", "triangles",
           "volume_rel_err", "mean_distance_m")


def fail(path, problem):
    print(f"plot_ct_study: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def label(r):
    return f"h×{float(r['voxel_factor']):g} s{r['smoothing']} a{float(r['adaptivity']):g}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    a = ap.parse_args()
    path = os.path.join(a.dir, "ct_study.csv")
    out = a.out or os.path.join(a.dir, "ct_study.png")
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or any(c not in rows[0] for c in COLUMNS):
            fail(path, "header lacks some of " + ",".join(COLUMNS))
        for r in rows:
            for c in COLUMNS[1:]:
                float(r[c])
    except OSError as e:
        fail(path, e.strerror)
    except ValueError as e:
        fail(path, f"not a number ({e})")
    cases = sorted({r["case"] for r in rows})
    colours = dict(zip(cases, ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")))
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for r in rows:
        t = float(r["seconds"])
        d = float(r["mean_distance_m"]) / float(r["finest_voxel_m"])
        c = colours[r["case"]]
        default = r["voxel_factor"] == "1" and r["smoothing"] == "2" and r["adaptivity"] == "0.1"
        ax.plot(t, d, "o", color=c, mfc=c if default else "none", ms=7)
        ax.annotate(label(r), (t, d), fontsize=6, xytext=(3, 2), textcoords="offset points")
        ax2.plot(t, 100 * float(r["volume_rel_err"]), "s", color=c, mfc="none")
        ax2.plot(t, float(r["triangles"]) / 1e4, "^", color=c, mfc="none")
    for case in cases:
        ax.plot([], [], "o", color=colours[case], label=case)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8, label="acceptance: one voxel")
    ax.set_xlabel("import time, read + surface [s] (2 cores)")
    ax.set_ylabel("mean surface distance to marching cubes [voxels]")
    ax.set_ylim(0, 1.1)
    ax.set_title("error against runtime (filled: the default setting)", fontsize=10)
    ax.legend(fontsize=8)
    ax2.plot([], [], "ks", mfc="none", label="volume error [%]")
    ax2.plot([], [], "k^", mfc="none", label="triangles [×10⁴]")
    ax2.axhline(-10, color="grey", ls="--", lw=0.8)
    ax2.set_xlabel("import time [s]")
    ax2.set_title("volume against the reference (acceptance ±10 %) and mesh size", fontsize=10)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    print(out)


if __name__ == "__main__":
    main()
