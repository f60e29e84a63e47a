#!/usr/bin/env python3
"""The generation-4 batch at several edge lengths and time steps: per-trial peak wall forces, how far each setting's
agree with the next finer one's, and a figure (docs/growth-and-contact.md, "Resolution study").

Each batch is `magvine trials SCENE --targets 0-0-0-0-1,0-0-1-1-0,0-1-0-1-1,0-1-1-0-0 --repeats 4 --jobs 2
--keep-runs --out DIR`, SCENE the generation-4 scene with `recover: {retries: 0}` and `growth.edge_length` or
`simulation.dt` changed. This reads each DIR/runs/*/metrics.json (`max_wall_normal_N`, the largest force on a node;
`max_wall_line_load_N_per_mm`, the largest over the length a node stands for), writes one CSV row per trial, prints
a Markdown table of the pairs (each time step against its half at one edge length, each edge length against the
next finer at one time step: the trials within 15 %, the median and largest difference relative to the finer) and
draws both peaks against the edge length at one time step.

Usage: /usr/bin/python3 tools/generation4_resolution.py --csv OUT.csv [--png OUT.png] [--dt-ms 10] EDGE_MM:DT_MS:DIR ...
"""
import argparse
import csv
import functools
import json
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tool_errors import input_error  # noqa: E402

KEYS = ("max_wall_normal_N", "max_wall_line_load_N_per_mm")
TOLERANCE = 0.15  # issue 28's resolution item: per-trial peak within 15 % between the two finest settings


fail = functools.partial(input_error, "generation4_resolution")


def read_batch(folder):
    runs = os.path.join(folder, "runs")
    if not os.path.isdir(runs):
        fail(folder, "no runs/ folder (run magvine trials with --keep-runs)")
    out = {}
    for name in sorted(os.listdir(runs)):
        path = os.path.join(runs, name, "metrics.json")
        try:
            with open(path) as f:
                m = json.load(f)
            out[name] = {k: float(m[k]) for k in KEYS} | {"success": int(m["success"]), "failed": int(m["failed_steps"])}
        except (OSError, ValueError, KeyError) as e:
            fail(path, e)
    return out


def agreement(coarse, fine, key):
    common = sorted(set(coarse) & set(fine))
    if not common:
        fail("batches", "two share no trial (the same --targets and --repeats?)")
    d = [abs(coarse[t][key] - fine[t][key]) / max(fine[t][key], 1e-12) for t in common]
    return sum(x <= TOLERANCE for x in d), len(d), statistics.median(d), max(d)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--csv", required=True)
    p.add_argument("--png")
    p.add_argument("--dt-ms", type=float, default=10.0, help="the time step whose edge lengths the figure draws")
    p.add_argument("batches", nargs="+", metavar="EDGE_MM:DT_MS:DIR")
    a = p.parse_args()
    batches = {}
    for spec in a.batches:
        try:
            edge, dt, folder = spec.split(":", 2)
            batches[(float(edge), float(dt))] = read_batch(folder)
        except ValueError:
            fail(spec, "expected EDGE_MM:DT_MS:DIR")
    lines = ["| pair | reached | node force within 15 % | line load within 15 % |", "|---|---|---|---|"]
    pairs = []
    for edge in sorted({e for e, _ in batches}, reverse=True):
        steps = sorted((d for e, d in batches if e == edge), reverse=True)
        pairs += [(f"h = {edge:g} mm: dt {c:g} vs {f:g} ms", (edge, c), (edge, f)) for c, f in zip(steps, steps[1:])]
    for dt in sorted({d for _, d in batches}, reverse=True):
        edges = sorted((e for e, d in batches if d == dt), reverse=True)
        pairs += [(f"dt = {dt:g} ms: h {c:g} vs {f:g} mm", (c, dt), (f, dt)) for c, f in zip(edges, edges[1:])]
    for label, c, f in pairs:
        cells = []
        for key in KEYS:
            n, total, median, largest = agreement(batches[c], batches[f], key)
            cells.append(f"{n}/{total} (median {100 * median:.1f} %, largest {100 * largest:.1f} %)")
        reached = f"{sum(v['success'] for v in batches[c].values())}, {sum(v['success'] for v in batches[f].values())}"
        lines.append(f"| {label} | {reached} | {cells[0]} | {cells[1]} |")
    figure_edges = sorted(e for e, d in batches if d == a.dt_ms)
    if a.png and len(figure_edges) < 2:
        fail("--png", f"fewer than two edge lengths at dt = {a.dt_ms:g} ms")
    if a.png:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError as e:
            fail("--png", f"needs matplotlib ({e})")
    with open(a.csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["edge_mm", "dt_ms", "trial", "success", "failed_steps", *KEYS])
        for (edge, dt), trials in sorted(batches.items(), key=lambda x: (-x[0][0], -x[0][1])):
            for t, v in trials.items():
                w.writerow([edge, dt, t, v["success"], v["failed"], f"{v[KEYS[0]]:.4f}", f"{v[KEYS[1]]:.4f}"])
    print("\n".join(lines))
    if a.png:
        edges = figure_edges
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        trials = sorted(batches[(edges[0], a.dt_ms)])
        for ax, key, title in zip(axes, KEYS, ("largest force on a node [N]", "largest line load [N/mm]")):
            for t in trials:
                ax.plot(edges, [batches[(e, a.dt_ms)][t][key] for e in edges], "o-", lw=0.8, ms=3, alpha=0.7)
            ax.set_xscale("log")
            ax.minorticks_off()
            ax.set_xticks(edges, [f"{e:g}" for e in edges])
            ax.set_xlabel("edge length h [mm]")
            ax.set_title(title, fontsize=10)
            ax.grid(alpha=0.3)
        fig.suptitle(f"generation-4 batch, per trial (16), dt = {a.dt_ms:g} ms", fontsize=10)
        fig.tight_layout()
        fig.savefig(a.png, dpi=110)


if __name__ == "__main__":
    main()
