"""A parameter sweep in threads: the Y phantom's bench run with the EPM's resting point moved along y, each run a
dict scene handed to magvine.run on a concurrent.futures thread pool (the core releases the GIL, so the runs use
every core). Writes a CSV and a plot of success and time to target against the EPM's position (docs/python.md).

    PYTHONPATH=$(make -s python-path) /usr/bin/python3 examples/python/sweep.py --out sweep
"""
import argparse
import copy
import csv
import os
from concurrent.futures import ThreadPoolExecutor

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

import magvine  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="assets/scenes/y_bifurcation_fluid_vine.yaml")
    parser.add_argument("--out", default="sweep")
    parser.add_argument("--y", type=float, nargs="+", default=[90, 100, 110, 120, 140, 160, 180, 200],
                        help="the EPM's resting y [mm] (its last keyframe)")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    args = parser.parse_args()
    with open(args.scene) as f:
        base = yaml.safe_load(f)
    # A scene dict resolves relative paths against the working directory: the Y phantom has none.

    def run(y):
        scene = copy.deepcopy(base)
        scene["control"]["magnets"][0]["keyframes"][-1]["position"][1] = y
        return magvine.run(scene)

    with ThreadPoolExecutor(max_workers=args.threads) as pool:
        results = list(pool.map(run, args.y))
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "sweep.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["epm_y_mm", "success", "time_to_target_s", "max_wall_normal_N", "path_progress", "runtime_s"])
        for y, m in zip(args.y, results):
            w.writerow([y, m["success"], m["time_to_target_s"], m["max_wall_normal_N"], m["path_progress"],
                        m["runtime_s"]])
    fig, ax = plt.subplots(figsize=(6, 4))
    ok = [m["success"] for m in results]
    t = [m["time_to_target_s"] if m["success"] else np.nan for m in results]
    ax.plot(args.y, t, "o-", label="time to target")
    for y, s in zip(args.y, ok):
        if not s:
            ax.axvline(y, color="r", alpha=0.3)
    ax.set_xlabel("EPM resting y [mm] (red: target not reached)")
    ax.set_ylabel("time to target [s]")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "sweep.png"), dpi=120)
    print(f"{args.out}/sweep.csv, sweep.png: {sum(ok)}/{len(ok)} reached the target")


if __name__ == "__main__":
    main()
