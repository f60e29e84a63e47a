#!/usr/bin/python3
"""Plot a planar field map written by `magvine field-map`.

Reads field_map.csv (columns u,v,x,y,z,Bx,By,Bz,B,gradB in SI units, u varying
fastest) and its field_map.json sidecar, and writes a two-panel PNG: |B| in mT
with in-plane field-direction streamlines (left) and |grad B| in mT/m (right),
both on logarithmic colour scales, with magnet outlines and magnetisation
arrows drawn on top.

Usage:
    /usr/bin/python3 tools/plot_field_map.py CSV --out PNG [--title TEXT] [--json JSON]

Exit status 2 (one line on stderr, nothing written) for a missing or malformed
input file.
"""
import argparse
import json
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

COLUMNS = ("u", "v", "x", "y", "z", "Bx", "By", "Bz", "B", "gradB")
B_RANGE, B_LEVELS = (1.0, 1000.0), (10.0, 56.0, 100.0)  # mT
G_RANGE, G_LEVELS = (10.0, 1e5), (100.0, 1000.0, 10000.0)  # mT/m


class InputError(Exception):
    """A missing or malformed input file, reported as 'FILE: problem'."""


def load(csv_path, json_path):
    """Return (meta dict, dict of resolution x resolution grids, u fastest)."""
    try:
        with open(json_path, encoding="utf-8") as f:
            meta = json.load(f)
        plane, n = meta["plane"], int(meta["resolution"])
        sources = meta.get("sources", [])
        if len(plane) != 2 or plane[0] not in "xyz" or plane[1] not in "xyz" or n < 2:
            raise ValueError("bad plane or resolution")
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{json_path}: {e}") from None
    try:
        with open(csv_path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
            data = np.loadtxt(f, delimiter=",", ndmin=2)
    except (OSError, ValueError) as e:
        raise InputError(f"{csv_path}: {e}") from None
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise InputError(f"{csv_path}: missing column(s) {', '.join(missing)}")
    if data.shape != (n * n, len(header)):
        raise InputError(f"{csv_path}: expected {n * n} rows of {len(header)} values, "
                         f"got {data.shape[0]}x{data.shape[1]}")
    if not np.all(np.isfinite(data)):
        raise InputError(f"{csv_path}: non-finite values")
    grids = {c: data[:, header.index(c)].reshape(n, n) for c in COLUMNS}
    return {"plane": plane, "sources": sources}, grids


def draw_sources(ax, sources, half_width_mm):
    """Grey magnet outlines on top of the field, with a magnetisation arrow."""
    for src in sources:
        try:
            cu, cv = (1e3 * float(c) for c in src["position_uv_m"])
            du, dv = (float(c) for c in src["direction_uv"])
        except (KeyError, TypeError, ValueError):
            continue
        outline = src.get("outline_uv_m")
        if outline:
            pts = 1e3 * np.asarray(outline, dtype=float)
            ax.add_patch(Polygon(pts, closed=True, facecolor="0.75", edgecolor="black",
                                 linewidth=1.0, zorder=5))
            size = 0.7 * min(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]))
        else:
            size = 0.08 * half_width_mm
        ax.annotate("", xy=(cu + 0.5 * size * du, cv + 0.5 * size * dv),
                    xytext=(cu - 0.5 * size * du, cv - 0.5 * size * dv),
                    arrowprops=dict(arrowstyle="-|>", color="black", lw=1.8,
                                    mutation_scale=14), zorder=6)


def level_text(unit):
    """Contour label formatter: 10^n for large powers of ten, plain otherwise."""
    def fmt(x):
        n = np.log10(x)
        return f"$10^{{{n:.0f}}}$ {unit}" if n >= 3 and n == round(n) else f"{x:g} {unit}"
    return fmt


def label_spots(u_mm, v_mm, values, levels, origin, angle_deg):
    """Where a ray from origin first drops below each level (for contour labels)."""
    r = np.linspace(0.0, min(u_mm[-1] - u_mm[0], v_mm[-1] - v_mm[0]), 2000)
    t = np.radians(angle_deg)
    pu, pv = origin[0] + r * np.cos(t), origin[1] + r * np.sin(t)
    keep = (pu > u_mm[0]) & (pu < u_mm[-1]) & (pv > v_mm[0]) & (pv < v_mm[-1])
    pu, pv = pu[keep], pv[keep]
    iu, iv = np.searchsorted(u_mm, pu), np.searchsorted(v_mm, pv)
    ray = values[iv, iu]
    spots = []
    for level in levels:
        above = np.nonzero(ray >= level)[0]
        below = np.nonzero(ray < level)[0]
        below = below[below > above[0]] if above.size else below
        if below.size:
            spots.append((pu[below[0]], pv[below[0]]))
    return spots


def panel(fig, ax, meta, g, values, vrange, levels, cmap, label, unit, angle):
    """One log-scaled colour map with labelled contours and a colour bar."""
    u_mm, v_mm = 1e3 * g["u"][0, :], 1e3 * g["v"][:, 0]
    norm = LogNorm(*vrange)
    mesh = ax.pcolormesh(u_mm, v_mm, np.clip(values, *vrange), norm=norm, cmap=cmap,
                         shading="auto", rasterized=True)
    # White contours on dark parts of the colour map, black on light parts.
    rgb = plt.get_cmap(cmap)(norm(np.asarray(levels)))[:, :3]
    ink = ["black" if c @ (0.299, 0.587, 0.114) > 0.55 else "white" for c in rgb]
    cs = ax.contour(u_mm, v_mm, values, levels=levels, colors=ink,
                    linewidths=0.8, linestyles="--")
    srcs = meta["sources"]
    origin = 1e3 * np.asarray(srcs[0]["position_uv_m"], float) if srcs else (0.0, 0.0)
    ax.clabel(cs, fmt=level_text(unit), fontsize=8, inline_spacing=3,
              manual=label_spots(u_mm, v_mm, values, levels, origin, angle))
    fig.colorbar(mesh, ax=ax, shrink=0.82, pad=0.03).set_label(label)
    a, b = meta["plane"]
    ax.set_xlabel(f"{a} [mm]")
    ax.set_ylabel(f"{b} [mm]")
    ax.set_aspect("equal")
    ax.set_xlim(u_mm[0], u_mm[-1])
    ax.set_ylim(v_mm[0], v_mm[-1])
    draw_sources(ax, meta["sources"], u_mm[-1])
    return u_mm, v_mm


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv")
    p.add_argument("--out", required=True, help="output PNG")
    p.add_argument("--title", default=None)
    p.add_argument("--json", default=None, help="sidecar (default: CSV with .json)")
    args = p.parse_args()
    json_path = args.json or os.path.splitext(args.csv)[0] + ".json"
    try:
        meta, g = load(args.csv, json_path)
    except InputError as e:
        print(f"plot_field_map: {e}", file=sys.stderr)
        return 2

    comp = {c: g["B" + c] for c in "xyz"}
    bu, bv = comp[meta["plane"][0]], comp[meta["plane"][1]]
    fig, (ax_b, ax_g) = plt.subplots(1, 2, figsize=(12, 5.2), constrained_layout=True)
    u_mm, v_mm = panel(fig, ax_b, meta, g, 1e3 * g["B"], B_RANGE, B_LEVELS,
                       "viridis", r"$|\mathbf{B}|$ [mT]", "mT", 100)
    ax_b.streamplot(u_mm, v_mm, bu, bv, density=1.3, color=(1, 1, 1, 0.55),
                    linewidth=0.6, arrowsize=0.7, zorder=4)
    panel(fig, ax_g, meta, g, 1e3 * g["gradB"], G_RANGE, G_LEVELS,
          "magma", r"$\|\nabla\mathbf{B}\|_F$ [mT/m]", "mT/m", 70)
    ax_b.set_title(r"Field magnitude $|\mathbf{B}|$")
    ax_g.set_title(r"Gradient magnitude $\|\nabla\mathbf{B}\|_F$")
    if args.title:
        fig.suptitle(args.title, fontsize=14)

    tmp = f"{args.out}.tmp-{os.getpid()}"  # same folder, so os.replace is atomic
    try:
        with open(tmp, "xb") as f:
            fig.savefig(f, format="png", dpi=150)
        os.replace(tmp, args.out)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
