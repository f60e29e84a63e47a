#!/usr/bin/python3
"""Plot the MPM sweep of thesis fig 3.7 from `magvine mpm` runs of the bundled sweep scenes.

The obstacle beam (assets/scenes/mpm_obstacle_sweep.yaml, and mpm_obstacle_sweep_free.yaml without the block) under an
upward field ramped from 0 at --ramp-start to --ramp-top mT at the run's end: the tip's height over the beam's
length, δ/L, against the field. A missing or malformed input gives one line on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_mpm_sweeps.py --obstacle runs/obstacle_sweep --free runs/obstacle_sweep_free \\
        --out docs/figures/mpm_obstacle_sweep.png
"""
import argparse
import csv
import os
import subprocess
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def fail(path, problem):
    print(f"plot_mpm_sweeps: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def run_mpm(magvine, scene, run, tool):
    """`magvine mpm SCENE --out RUN` for a sweep tool: its wall time [s]. When magvine cannot start or exits non-zero,
    one line on stderr naming `tool`, the file and magvine's last line, and exit status 2."""
    start = time.monotonic()
    try:
        done = subprocess.run([magvine, "mpm", scene, "--out", run], stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    except OSError as e:
        print(f"{tool}: {magvine}: {e.strerror}", file=sys.stderr)
        sys.exit(2)
    if done.returncode != 0:
        last_line = (done.stderr.strip().splitlines() or ["no message"])[-1]
        print(f"{tool}: {scene}: magvine mpm exited {done.returncode}: {last_line}", file=sys.stderr)
        sys.exit(2)
    return time.monotonic() - start


def tip_track(run):
    """(t [s], tip z [mm]) of the run's probes.csv."""
    path = os.path.join(run, "probes.csv")
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or "t_s" not in rows[0] or "tip_z_mm" not in rows[0]:
            fail(path, "no t_s and tip_z_mm columns (a run of a bundled sweep scene?)")
        return [float(r["t_s"]) for r in rows], [float(r["tip_z_mm"]) for r in rows]
    except OSError as e:
        fail(path, e.strerror)
    except ValueError as e:
        fail(path, f"not a number ({e})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--obstacle", required=True, help="output folder of mpm_obstacle_sweep.yaml")
    ap.add_argument("--free", help="output folder of mpm_obstacle_sweep_free.yaml")
    ap.add_argument("--ramp-start", type=float, default=0.3, help="when the field ramp starts [s]")
    ap.add_argument("--ramp-top", type=float, default=15.0, help="the field at the run's end [mT]")
    ap.add_argument("--length", type=float, default=60.0, help="the beam's free length [mm]")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()

    fig, ax2 = plt.subplots(1, 1, figsize=(6, 4.2))

    for run, label, colour in ((a.obstacle, "with the block", "C1"), (a.free, "without the block", "C2")):
        if not run:
            continue
        t, z = tip_track(run)
        end = t[-1]
        pairs = [(a.ramp_top * (ti - a.ramp_start) / (end - a.ramp_start), zi / a.length)
                 for ti, zi in zip(t, z) if ti >= a.ramp_start]
        ax2.plot([p[0] for p in pairs], [p[1] for p in pairs], "-", color=colour, label=label)
    ax2.set_xlabel("applied field [mT]")
    ax2.set_ylabel("tip height δ/L")
    ax2.set_title("Beam lifted into an obstacle (thesis fig 3.7)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(a.out)


if __name__ == "__main__":
    main()
