#!/usr/bin/python3
"""Plot a growth experiment written by `magvine run` (a scene with anatomy:).

Left: a view (mm) on the plane of the run's two widest extents, or the one
--plane names, of the phantom's centreline graph drawn at its lumen width
(when graph.json is there), the final body, the tip's path coloured by
time, the magnets' path and the target, with the final body's nodes on the
wall ringed (area following shape.csv's normal_N). Right: everted length, and
the wall's largest normal force and total shear, against time. A missing or malformed
input gives one line on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_experiment.py RUN_DIR --out PNG [--title T] [--plane xy|xz|yz]
"""
import argparse
import csv
import json
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402


def fail(path, problem):
    """Report a bad input or output file in one line and exit with status 2."""
    print(f"plot_experiment: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def read_csv(path, needed):
    """Columns of a CSV file as float arrays (text columns kept as strings)."""
    try:
        with open(path, encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        fail(path, e.strerror)
    if not rows or not set(needed) <= set(rows[0]):
        fail(path, f"header lacks some of {','.join(needed)}")
    cols = {}
    for i, name in enumerate(rows[0]):
        values = [r[i] for r in rows[1:]]
        try:
            cols[name] = np.asarray(values, float)
        except ValueError:
            cols[name] = values
    for name in needed:
        if not isinstance(cols[name], np.ndarray) or not np.all(np.isfinite(cols[name])):
            fail(path, f"column {name} is not all finite numbers")
    return cols


def read_graph(path):
    try:
        with open(path, encoding="utf-8") as f:
            graph = json.load(f)
        return graph, np.asarray([n["position"] for n in graph["nodes"]], float)
    except (OSError, KeyError, ValueError, TypeError, IndexError) as e:
        fail(path, getattr(e, "strerror", None) or f"malformed graph ({e})")


def draw_graph(ax, path, graph, axes):
    """The phantom's lumen as overlapping discs of its radius along the centreline, and the branch names, on the
    plane of coordinates `axes` (a pair of 0, 1, 2)."""
    try:
        nodes = graph["nodes"]
        for b in graph["branches"]:
            pts = np.asarray([nodes[i]["position"] for i in b["nodes"]], float)[:, list(axes)]
            radii = [nodes[i]["radius"] for i in b["nodes"]]
            for k in range(len(pts) - 1):  # discs every quarter radius along each segment
                n = max(2, int(np.hypot(*(pts[k + 1, :2] - pts[k, :2])) / (0.25 * radii[k])))
                for u in np.linspace(0.0, 1.0, n):
                    c = (1 - u) * pts[k, :2] + u * pts[k + 1, :2]
                    r = (1 - u) * radii[k] + u * radii[k + 1]
                    ax.add_patch(Circle(c, r, color="0.9", lw=0, zorder=0))
            ax.plot(pts[:, 0], pts[:, 1], color="0.7", lw=0.8, ls=":", zorder=1)
            ax.annotate(b["name"], pts[len(pts) // 2, :2], fontsize=7, color="0.4", zorder=2)
    except (OSError, KeyError, ValueError, TypeError, IndexError) as e:
        fail(path, getattr(e, "strerror", None) or f"malformed graph ({e})")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default="")
    p.add_argument("--plane", choices=("xy", "xz", "yz"), default=None,
                   help="the view's plane (default: the run's two widest extents)")
    a = p.parse_args()
    tip = read_csv(os.path.join(a.run_dir, "tip_trajectory.csv"),
                   ("t_s", "x_m", "y_m", "z_m", "length_m", "max_normal_N", "total_shear_N"))
    shape = read_csv(os.path.join(a.run_dir, "shape.csv"), ("x_m", "y_m", "z_m"))
    metrics_path = os.path.join(a.run_dir, "metrics.json")
    try:
        with open(metrics_path, encoding="utf-8") as f:
            metrics = json.load(f)
    except (OSError, ValueError) as e:
        fail(metrics_path, getattr(e, "strerror", None) or str(e))

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [1.3, 1]})
    graph_path = os.path.join(a.run_dir, "graph.json")
    graph = read_graph(graph_path) if os.path.exists(graph_path) else None
    if a.plane:
        axes = tuple("xyz".index(c) for c in a.plane)
    else:
        pts = np.column_stack([tip["x_m"], tip["y_m"], tip["z_m"]])
        if graph is not None:
            pts = np.vstack([pts, graph[1]])
        axes = tuple(sorted(np.argsort(np.ptp(pts, axis=0))[1:]))
    u, v = ("xyz"[axes[0]] + "_m", "xyz"[axes[1]] + "_m")
    if graph is not None:
        draw_graph(ax, graph_path, graph[0], axes)
    ax.plot(1e3 * shape[u], 1e3 * shape[v], "-", color="tab:orange", lw=3, label="vine (final)", zorder=3)
    if "normal_N" in shape and np.any(shape["normal_N"] > 0):  # the final body's wall forces, per node
        f = np.asarray(shape["normal_N"], float)
        on = f > 0
        ax.scatter(1e3 * shape[u][on], 1e3 * shape[v][on], s=80 * f[on] / f.max() + 4, facecolors="none",
                   edgecolors="tab:red", lw=0.8, zorder=5,
                   label="wall normal force per node (area ∝ force, largest %.2f N)" % f.max())
    sc = ax.scatter(1e3 * tip[u], 1e3 * tip[v], c=tip["t_s"], s=4, cmap="viridis", zorder=4,
                    label="tip path")
    fig.colorbar(sc, ax=ax, label="time [s]", shrink=0.8)
    magnets = os.path.join(a.run_dir, "magnet_trajectory.csv")
    if os.path.exists(magnets):
        m = read_csv(magnets, ("t_s", "magnet", "x_m", "y_m", "z_m"))
        for k in np.unique(m["magnet"]):
            sel = m["magnet"] == k
            x, y = 1e3 * m[u][sel], 1e3 * m[v][sel]
            ax.plot(x, y, "--", color="tab:red", lw=1.2, label="magnet centre (path)" if k == 0 else None, zorder=3)
            ax.plot(x[-1:], y[-1:], "s", color="tab:red", ms=7, zorder=3)
    target = metrics.get("tip_position_m")
    if metrics.get("final_tip_error_m") is not None and target is not None:
        ax.set_title(("target reached at %.2f s" % metrics["time_to_target_s"]) if metrics.get("success")
                     else "target not reached (final error %.1f mm)" % (1e3 * metrics["final_tip_error_m"]),
                     fontsize=10)
    ax.set_xlabel(u[0] + " [mm]")
    ax.set_ylabel(v[0] + " [mm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(alpha=0.3)

    ax2.plot(tip["t_s"], 1e3 * tip["length_m"], color="tab:orange", label="everted length [mm]")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("everted length [mm]")
    ax3 = ax2.twinx()
    for key, colour, label in (("max_normal_N", "tab:blue", "largest normal force on a node"),
                               ("total_shear_N", "tab:green", "total shear")):
        ax3.plot(tip["t_s"], 1e3 * tip[key], color=colour, lw=1, label=label)
    ax3.set_ylabel("wall force [mN]")
    lines = ax2.get_lines() + ax3.get_lines()
    ax2.legend(lines, [line.get_label() for line in lines], loc="upper left", fontsize=8)
    ax2.grid(alpha=0.3)
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    try:
        fig.savefig(a.out, dpi=130)
    except OSError as e:
        fail(a.out, e.strerror)


if __name__ == "__main__":
    main()
