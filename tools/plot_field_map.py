#!/usr/bin/python3
"""Plot a planar field map written by `magvine field-map` (CSV + JSON sidecar).

Two panels on log colour scales: |B| in mT with in-plane field streamlines, and
the Frobenius norm of grad B in mT/m; labelled contours, magnet outlines and
magnetisation arrows on both. A missing or malformed input gives one line on
stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_field_map.py CSV --out PNG [--title T] [--json J]
"""
import argparse
import json
import os
import sys
import warnings

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

COLUMNS = ("u", "v", "x", "y", "z", "Bx", "By", "Bz", "B", "gradB")
B_NAME, G_NAME = r"$|\mathbf{B}|$", r"$\|\nabla\mathbf{B}\|_F$"
B_RANGE, B_LEVELS = (1.0, 1e3), (10.0, 56.0, 100.0)  # mT
G_RANGE, G_LEVELS = (10.0, 1e5), (100.0, 1e3, 1e4)  # mT/m


def fail(path, problem):
    """Report a bad input or output file in one line and exit with status 2."""
    print(f"plot_field_map: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def load(csv_path, json_path):
    """Return (meta, grids): grids maps each CSV column to a [v, u] array."""
    try:
        with open(csv_path, encoding="utf-8") as f, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty file fails the row check below
            header = f.readline().strip().split(",")
            data = np.loadtxt(f, delimiter=",", ndmin=2)
    except (OSError, ValueError) as e:
        fail(csv_path, getattr(e, "strerror", None) or str(e).split(";")[0])
    if not set(COLUMNS) <= set(header):
        fail(csv_path, f"header lacks some of {','.join(COLUMNS)}")
    try:
        with open(json_path, encoding="utf-8") as f:
            meta = json.load(f)
        plane, n = str(meta["plane"]), int(meta["resolution"])
        if len(plane) != 2 or not set(plane) <= set("xyz") or n < 2:
            raise ValueError(f"bad plane {plane!r} or resolution {n}")
        for src in meta.setdefault("sources", []):  # raises if malformed
            if src.get("kind") != "uniform":
                np.asarray(src["position_uv_m"], float).reshape(2)
                np.asarray(src["direction_uv"], float).reshape(2)
            if np.asarray(src.get("outline_uv_m") or [[0, 0]], float).shape[1:] != (2,):
                raise ValueError(f"bad outline_uv_m in source {src.get('name')!r}")
    except (OSError, KeyError, ValueError, TypeError, AttributeError) as e:
        fail(json_path, getattr(e, "strerror", None) or
             (f"missing key {e}" if isinstance(e, KeyError) else e))
    if data.shape != (n * n, len(header)):
        fail(csv_path, f"expected {n}x{n} rows of {len(header)} numbers, "
                       f"got {data.shape[0]} rows of {data.shape[1]}")
    if not np.all(np.isfinite(data)):
        fail(csv_path, "non-finite values")
    g = {c: data[:, header.index(c)].reshape(n, n) for c in COLUMNS}
    if np.any(np.diff(g["u"][0]) <= 0) or np.any(np.diff(g["v"][:, 0]) <= 0):
        fail(csv_path, "rows are not a grid with u varying fastest")
    return meta, g


def draw_sources(ax, sources, arrow_mm):
    """Grey magnet outlines hiding the field inside, and magnetisation arrows."""
    for src in (s for s in sources if s.get("kind") != "uniform"):
        centre = 1e3 * np.asarray(src["position_uv_m"], float)
        d = np.asarray(src["direction_uv"], float)
        outline = 1e3 * np.asarray(src.get("outline_uv_m") or [], float)
        if len(outline) >= 3:
            ax.add_patch(Polygon(outline, facecolor="0.75", edgecolor="black",
                                 linewidth=1.0, zorder=5))
            arrow_mm = 0.7 * min(np.ptp(outline, axis=0))
        if np.hypot(*d) > 0.1:  # skip magnetisation (nearly) normal to the plane
            ax.annotate("", xy=centre + arrow_mm * d / 2, xytext=centre - arrow_mm * d / 2,
                        arrowprops=dict(arrowstyle="-|>", color="black", lw=1.8,
                                        mutation_scale=14), zorder=6)


def level_text(unit):
    """Contour label formatter: 10^n for powers of ten from 1000 up."""
    def fmt(x):
        n = np.log10(x)
        return f"$10^{{{n:.0f}}}$ {unit}" if n >= 3 and n == round(n) else f"{x:g} {unit}"
    return fmt


def label_spots(u_mm, v_mm, values, levels, origin, angle_deg):
    """Where a ray from origin first falls below each level: contour label spots."""
    r = np.linspace(0.0, u_mm[-1] - u_mm[0] + v_mm[-1] - v_mm[0], 4000)
    pu = origin[0] + r * np.cos(np.radians(angle_deg))
    pv = origin[1] + r * np.sin(np.radians(angle_deg))
    inside = (pu > u_mm[0]) & (pu < u_mm[-1]) & (pv > v_mm[0]) & (pv < v_mm[-1])
    pu, pv = pu[inside], pv[inside]
    ray = values[np.searchsorted(v_mm, pv), np.searchsorted(u_mm, pu)]
    spots = []
    for level in levels:
        above = np.nonzero(ray >= level)[0]
        below = np.nonzero(ray < level)[0]
        below = below[below > above[0]] if above.size else below[:0]
        if below.size:
            spots.append((pu[below[0]], pv[below[0]]))
    return spots


def panel(fig, ax, meta, u_mm, v_mm, values, vrange, levels, cmap, name, unit, angle):
    """One log-scaled colour map with labelled contours and a colour bar."""
    norm = LogNorm(*vrange)
    mesh = ax.pcolormesh(u_mm, v_mm, np.clip(values, *vrange), norm=norm, cmap=cmap,
                         shading="gouraud", rasterized=True)
    levels = [lv for lv in levels if values.min() < lv < values.max()]
    if levels:  # white contours over dark colours, black over light ones
        rgb = plt.get_cmap(cmap)(norm(np.asarray(levels)))[:, :3]
        ink = ["black" if c @ (0.299, 0.587, 0.114) > 0.55 else "white" for c in rgb]
        cs = ax.contour(u_mm, v_mm, values, levels=levels, colors=ink,
                        linewidths=0.8, linestyles="--")
        pos = [s["position_uv_m"] for s in meta["sources"] if s.get("kind") != "uniform"]
        origin = 1e3 * np.asarray(pos[0], float) if pos else (0.0, 0.0)
        spots = label_spots(u_mm, v_mm, values, levels, origin, angle)
        ax.clabel(cs, fmt=level_text(unit), fontsize=8, inline_spacing=3,
                  manual=spots or False)
    fig.colorbar(mesh, ax=ax, shrink=0.82, pad=0.03).set_label(f"{name} [{unit}]")
    ax.set(xlabel=f"{meta['plane'][0]} [mm]", ylabel=f"{meta['plane'][1]} [mm]",
           xlim=(u_mm[0], u_mm[-1]), ylim=(v_mm[0], v_mm[-1]), aspect="equal")
    draw_sources(ax, meta["sources"], 0.08 * (u_mm[-1] - u_mm[0]))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv")
    p.add_argument("--out", required=True, help="output PNG")
    p.add_argument("--title", help="figure title")
    p.add_argument("--json", help="sidecar (default: CSV with .json)")
    args = p.parse_args()
    meta, g = load(args.csv, args.json or os.path.splitext(args.csv)[0] + ".json")

    u_mm, v_mm, (a, b) = 1e3 * g["u"][0], 1e3 * g["v"][:, 0], meta["plane"]
    fig, (ax_b, ax_g) = plt.subplots(1, 2, figsize=(12, 5.2), constrained_layout=True)
    panel(fig, ax_b, meta, u_mm, v_mm, 1e3 * g["B"], B_RANGE, B_LEVELS, "viridis",
          B_NAME, "mT", 100)
    ax_b.streamplot(u_mm, v_mm, g["B" + a], g["B" + b], density=1.3, linewidth=0.6,
                    color=(1, 1, 1, 0.55), arrowsize=0.7, zorder=4)
    panel(fig, ax_g, meta, u_mm, v_mm, 1e3 * g["gradB"], G_RANGE, G_LEVELS, "magma",
          G_NAME, "mT/m", 70)
    ax_b.set_title(f"Field magnitude {B_NAME}")
    ax_g.set_title(f"Gradient magnitude {G_NAME}")
    if args.title:
        fig.suptitle(args.title, fontsize=14)

    tmp = f"{args.out}.tmp-{os.getpid()}"  # same folder, so os.replace is atomic
    try:
        with open(tmp, "xb") as f:
            fig.savefig(f, format="png", dpi=150)
        os.replace(tmp, args.out)
    except OSError as e:
        fail(args.out, e.strerror or e)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


if __name__ == "__main__":
    main()
