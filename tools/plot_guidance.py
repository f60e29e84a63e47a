#!/usr/bin/python3
"""A camera-guided run at a glance (control.navigator.guidance: camera, frames: true): the tip camera's frame at the
first choice between lumens before each junction of the plan (the chosen opening green, the others yellow), the
navigator's dead-reckoned arc length along the plan against the tip's true one, and the angle between its magnet line
and the oracle's, from RUN_DIR/guidance.csv and RUN_DIR/guidance/*.png.

    /usr/bin/python3 tools/plot_guidance.py RUN_DIR --out PNG

A missing or malformed input gives one line on stderr, exit status 2 and no PNG.
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

COLUMNS = ("t_s", "estimated_arc_m", "true_arc_m", "lumens", "junction", "line_error_deg")


def fail(path, problem):
    print(f"plot_guidance: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def read_rows(path):
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        fail(path, e.strerror)
    if not rows:
        fail(path, "no placements")
    for c in COLUMNS:
        if c not in rows[0]:
            fail(path, f"no column {c}")
    try:
        return [{c: float(r[c]) for c in COLUMNS} for r in rows]
    except ValueError:
        fail(path, "a value is not a number")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--out", required=True)
    a = p.parse_args()
    rows = read_rows(os.path.join(a.run_dir, "guidance.csv"))
    # The first frame with a choice between lumens at each junction (frames are named by their time in ms).
    firsts = {}
    for r in rows:
        if r["lumens"] > 1 and r["junction"] >= 0 and r["junction"] not in firsts:
            name = os.path.join(a.run_dir, "guidance", "%06d.png" % round(1e3 * r["t_s"]))
            if os.path.exists(name):
                firsts[r["junction"]] = (r["t_s"], name)
    n = max(1, len(firsts))
    fig = plt.figure(figsize=(3.0 * max(n, 2), 6.2))
    grid = fig.add_gridspec(2, max(n, 2))
    for k, (junction, (t, name)) in enumerate(sorted(firsts.items())):
        ax = fig.add_subplot(grid[0, k])
        ax.imshow(mpimg.imread(name))
        ax.set_title(f"junction {int(junction) + 1} of the plan, {t:.1f} s", fontsize=9)
        ax.axis("off")
    half = max(n, 2) // 2
    t = [r["t_s"] for r in rows]
    ax = fig.add_subplot(grid[1, :half])
    ax.plot(t, [1e3 * r["true_arc_m"] for r in rows], label="tip (truth)")
    ax.plot(t, [1e3 * r["estimated_arc_m"] for r in rows], "--", label="dead reckoning")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("arc length along the plan [mm]")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(grid[1, half:])
    ax.plot(t, [r["line_error_deg"] for r in rows], ".-")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("magnet line vs the oracle's [deg]")
    fig.tight_layout()
    try:
        fig.savefig(a.out, dpi=90)
    except OSError as e:
        fail(a.out, e.strerror)


if __name__ == "__main__":
    main()
