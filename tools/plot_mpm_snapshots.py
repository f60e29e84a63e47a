#!/usr/bin/python3
"""Draw MPM particle snapshots written by `magvine mpm SCENE --out DIR` side by side: each panel an orthographic view
of the particles (mm) along --view with --up towards the top, coloured by body. A missing or malformed input gives
one line on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_mpm_snapshots.py DIR [--panels 4] [--view 0,-1,0] [--up 0,0,1] [--rect U0,V0,U1,V1 ...]
        [--out DIR/snapshots.png]

--rect draws a grey rectangle (an obstacle's outline) in the picture's own axes, mm.
"""
import argparse
import json
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def fail(path, problem):
    print(f"plot_mpm_snapshots: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def read_ply(path):
    try:
        with open(path, encoding="ascii") as f:
            text = f.read()
    except OSError as e:
        fail(path, e.strerror)
    head, _, body = text.partition("end_header\n")
    if not body:
        fail(path, "not an ASCII PLY with a header")
    try:
        data = np.array(body.split(), dtype=float).reshape(-1, 4)
    except ValueError:
        fail(path, "expected rows of x y z body")
    return data[:, :3], data[:, 3].astype(int)


def vec(text, name):
    try:
        v = np.array([float(t) for t in text.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.any(v):
        fail(name, "needs three numbers x,y,z, not all zero")
    return v / np.linalg.norm(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--panels", type=int, default=4)
    ap.add_argument("--view", default="0,-1,0")
    ap.add_argument("--up", default="0,0,1")
    ap.add_argument("--title", default="")
    ap.add_argument("--rect", action="append", default=[])
    ap.add_argument("--out")
    a = ap.parse_args()
    mpath = os.path.join(a.dir, "metrics.json")
    try:
        with open(mpath, encoding="utf-8") as f:
            metrics = json.load(f)
        snaps = metrics["snapshots"]
    except (OSError, ValueError, KeyError) as e:
        fail(mpath, f"cannot read the snapshot list ({e})")
    if not snaps or a.panels < 1:
        fail(mpath, "no snapshots")
    picks = sorted({round(i * (len(snaps) - 1) / max(1, a.panels - 1)) for i in range(a.panels)})
    d = vec(a.view, "--view")
    up = vec(a.up, "--up")
    up = up - up.dot(d) * d
    if np.linalg.norm(up) < 1e-9:
        fail("--up", "is parallel to --view")
    up /= np.linalg.norm(up)
    right = np.cross(d, up)
    rects = []
    for r in a.rect:
        try:
            u0, v0, u1, v1 = (float(t) for t in r.split(","))
        except ValueError:
            fail("--rect", f"needs four numbers U0,V0,U1,V1, got '{r}'")
        rects.append((min(u0, u1), min(v0, v1), abs(u1 - u0), abs(v1 - v0)))
    frames = [(snaps[i]["t_s"], *read_ply(os.path.join(a.dir, snaps[i]["file"]))) for i in picks]
    allx = np.concatenate([p @ right for _, p, _ in frames])
    ally = np.concatenate([p @ up for _, p, _ in frames])
    fig, axes = plt.subplots(1, len(frames), figsize=(3.2 * len(frames), 3.2), squeeze=False)
    for ax, (t, p, body) in zip(axes[0], frames):
        depth = p @ (-d)
        order = np.argsort(depth)
        ax.scatter((p @ right)[order], (p @ up)[order], c=body[order], cmap="tab10", vmin=0, vmax=9, s=0.6,
                   linewidths=0)
        for u, v, w, h in rects:
            ax.add_patch(plt.Rectangle((u, v), w, h, color="0.75", zorder=0))
        ax.set_xlim(allx.min() - 0.5, allx.max() + 0.5)
        ax.set_ylim(ally.min() - 0.5, ally.max() + 0.5)
        ax.set_aspect("equal")
        ax.set_title(f"t = {t * 1e3:.0f} ms", fontsize=9)
        ax.set_xlabel("mm", fontsize=8)
        ax.tick_params(labelsize=7)
    if a.title:
        fig.suptitle(a.title, fontsize=10)
    fig.tight_layout()
    out = a.out or os.path.join(a.dir, "snapshots.png")
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
