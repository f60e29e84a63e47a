#!/usr/bin/python3
"""Plot the MPM beam study written by `magvine study mpm-beam --out DIR`.

Left: tip deflection δ/L of the Zhao beam against the load B̄ = 12 (L/t)² Br B/(μ0 E'), the closed-form elastica
as a line and each MPM resolution as markers (hollow where a run did not come to rest). Right: mean absolute
percentage error over the fields against the total runtime of that resolution. A missing or malformed input gives one
line on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_mpm_study.py DIR [--out DIR/mpm_beam_study.png] [--compare DIR2]

--compare draws another study's error against runtime beside this one's (e.g. the other frame: --frame updated and
--frame total), each labelled with its frame.
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

POINTS = ("cells", "particles_per_cell", "particles", "bbar", "reference", "deflection", "settled", "ok", "seconds")
SUMMARY = ("cells", "particles_per_cell", "particles", "mape_pct", "seconds")


def fail(path, problem):
    print(f"plot_mpm_study: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def read(path, columns):
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows or any(c not in rows[0] for c in columns):
            fail(path, "header lacks some of " + ",".join(columns))
        return [{c: float(r[c]) for c in columns} for r in rows]
    except OSError as e:
        fail(path, e.strerror)
    except ValueError as e:
        fail(path, f"not a number ({e})")


def elastica(bbar):
    """δ/L of Euler's cantilever elastica under an axial dead load (closed form via K(k) by the AGM)."""
    root = math.sqrt(bbar)
    if root <= math.pi / 2:
        return 0.0

    def ellip_k(k):
        a, b = 1.0, math.sqrt(1.0 - k * k)
        while abs(a - b) > 1e-15:
            a, b = (a + b) / 2, math.sqrt(a * b)
        return math.pi / (2 * a)

    lo, hi = 0.0, 1.0 - 1e-16
    for _ in range(200):
        k = (lo + hi) / 2
        if ellip_k(k) < root:
            lo = k
        else:
            hi = k
    k = (lo + hi) / 2
    return 2 * k / ellip_k(k)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    ap.add_argument("--compare", help="another study's folder: its error against runtime drawn beside this one's")
    a = ap.parse_args()
    points = read(os.path.join(a.dir, "mpm_beam_study.csv"), POINTS)
    summary = read(os.path.join(a.dir, "mpm_beam_summary.csv"), SUMMARY)
    other = read(os.path.join(a.compare, "mpm_beam_summary.csv"), SUMMARY) if a.compare else []
    out = a.out or os.path.join(a.dir, "mpm_beam_study.png")
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    top = max(p["bbar"] for p in points) * 1.05
    xs = [2.4674 + i * (top - 2.4674) / 400 for i in range(401)]
    ax.plot(xs, [elastica(x) for x in xs], "k-", lw=1.5, label="elastica (closed form)")
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, s in enumerate(summary):
        mine = [p for p in points if p["cells"] == s["cells"] and p["particles_per_cell"] == s["particles_per_cell"]]
        c = colours[i % len(colours)]
        label = f"{int(s['cells'])} cells, {int(s['particles_per_cell'])}/cell ({int(s['particles'])} particles)"
        for j, p in enumerate(mine):
            filled = p["settled"] > 0 and p["ok"] > 0
            ax.plot(p["bbar"], p["deflection"], "o", color=c, mfc=c if filled else "none", label=label if j == 0 else None)
        ax2.plot(s["seconds"], s["mape_pct"], "o", color=c, label=label)
    # The experiment where the study knows it (Zhao et al. at 5 mT; older studies have no such column).
    with open(os.path.join(a.dir, "mpm_beam_study.csv"), encoding="utf-8", newline="") as f:
        raw = list(csv.DictReader(f))
    model = raw[0].get("model", "plane-strain")
    frame = raw[0].get("frame", "updated")
    if other:
        with open(os.path.join(a.compare, "mpm_beam_summary.csv"), encoding="utf-8", newline="") as f:
            other_frame = (list(csv.DictReader(f)) or [{}])[0].get("frame", "updated")
        ax2.plot([s["seconds"] for s in summary], [s["mape_pct"] for s in summary], "-", color="0.6", lw=1,
                 label=f"{frame}-Lagrangian (above)")
        ax2.plot([s["seconds"] for s in other], [s["mape_pct"] for s in other], "s--", color="0.3", mfc="none",
                 label=f"{other_frame}-Lagrangian, same resolutions")
    shown = set()
    for r, p in zip(raw, points):
        if r.get("experiment") and p["bbar"] not in shown:
            shown.add(p["bbar"])
            ax.plot(p["bbar"], float(r["experiment"]), "k*", ms=11,
                    label="Zhao et al., experiment" if len(shown) == 1 else None)
    ax.set_xlabel("B̄ = 12 (L/t)² Br B / (μ0 E')")
    ax.set_ylabel("tip deflection δ/L")
    ax.set_title(f"Zhao beam, field antiparallel to Br ({model}, {frame}-Lagrangian)")
    ax.legend(fontsize=7)
    ax2.axhline(6.1, color="grey", ls="--", lw=1, label="thesis: 6.1 % (vs experiment)")
    ax2.set_xscale("log")
    ax2.set_xlabel("runtime of the six fields, one core [s]")
    ax2.set_ylabel("MAPE vs elastica [%]")
    ax2.set_title("error against runtime")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(out)


if __name__ == "__main__":
    main()
