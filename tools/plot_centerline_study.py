#!/usr/bin/python3
"""Plot the airway-graph voxel study written by `magvine study centerline --out DIR`.

Left: error against extraction time (mean centreline distance and mean radius error relative to the
reference radius, and the radii's 95th percentile, which the junctions set, also without them); hollow markers where the
topology is not exact. Right: the same against the voxel edge. A missing or malformed input gives one line
on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_centerline_study.py DIR [--out DIR/centerline_study.png]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLUMNS = ("voxel_m", "seconds", "same_topology", "mean_distance_rel", "mean_radius_err", "p95_radius_err",
           "p95_radius_err_away")


def fail(path, problem):
    print(f"plot_centerline_study: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    a = ap.parse_args()
    path = os.path.join(a.dir, "centerline_study.csv")
    out = a.out or os.path.join(a.dir, "centerline_study.png")
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or any(c not in rows[0] for c in COLUMNS):
            fail(path, "header lacks some of " + ",".join(COLUMNS))
        data = {c: [float(r[c]) for r in rows] for c in COLUMNS}
    except OSError as e:
        fail(path, e.strerror)
    except ValueError as e:
        fail(path, f"not a number ({e})")
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    series = (("mean_distance_rel", "centreline distance (mean)", "tab:blue"),
              ("mean_radius_err", "radius error (mean)", "tab:orange"),
              ("p95_radius_err", "radius error (95th percentile)", "tab:red"),
              ("p95_radius_err_away", "radius error (95th percentile, away from junctions and ends)", "tab:purple"))
    for key, label, colour in series:
        y = [100 * v for v in data[key]]
        for axis, x in ((ax, data["seconds"]), (ax2, [1e3 * v for v in data["voxel_m"]])):
            axis.plot(x, y, "-", color=colour, label=label)
            exact = [i for i, t in enumerate(data["same_topology"]) if t == 1.0]
            wrong = [i for i, t in enumerate(data["same_topology"]) if t != 1.0]
            axis.plot([x[i] for i in exact], [y[i] for i in exact], "o", color=colour)
            axis.plot([x[i] for i in wrong], [y[i] for i in wrong], "o", mfc="none", color=colour)
    for axis in (ax, ax2):
        axis.axhline(10, color="0.5", ls=":", lw=1)
        axis.set_ylabel("error [% of the local radius]")
        axis.set_yscale("log")
        axis.grid(alpha=0.3, which="both")
    ax.set_xscale("log")
    ax.set_xlabel("extraction time [s] (one core)")
    ax2.set_xlabel("voxel edge [mm]")
    ax2.invert_xaxis()
    ax.legend(fontsize=8)
    fig.suptitle("Airway graph of the generated tree (generation 6, 127 branches) against its ground truth; "
                 "filled: topology exact", fontsize=10)
    fig.tight_layout()
    tmp = out + ".partial.png"
    try:
        fig.savefig(tmp, dpi=130)
        os.replace(tmp, out)
    except OSError as e:
        fail(out, e.strerror)


if __name__ == "__main__":
    main()
