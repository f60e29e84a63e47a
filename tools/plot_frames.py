#!/usr/bin/python3
"""A strip of video frames for a paper or the README, from the PNG frames a run writes with
`outputs.video: {..., frames: true}` (RUN_DIR/<camera>_frames/NNNNNN.png), each titled with its
simulated time (frame number × speed / fps, read from the scene's metrics.json video entry).

    /usr/bin/python3 tools/plot_frames.py RUN_DIR --camera tip --frames 0,100,200,300 --out PNG [--speed S]

A missing or malformed input gives one line on stderr, exit status 2 and no PNG.
"""
import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402


def fail(path, problem):
    print(f"plot_frames: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--camera", default="tip", choices=("tip", "overview"))
    p.add_argument("--frames", required=True, help="comma-separated frame numbers")
    p.add_argument("--speed", type=float, default=None, help="simulated seconds per video second (default: 1)")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default="")
    a = p.parse_args()
    try:
        frames = [int(f) for f in a.frames.split(",")]
    except ValueError:
        fail("--frames", f"'{a.frames}' is not a list of frame numbers")
    metrics_path = os.path.join(a.run_dir, "metrics.json")
    try:
        with open(metrics_path, encoding="utf-8") as f:
            videos = {v["camera"]: v for v in json.load(f).get("videos", [])}
    except (OSError, ValueError, KeyError, TypeError) as e:
        fail(metrics_path, getattr(e, "strerror", None) or f"malformed ({e})")
    if a.camera not in videos:
        fail(metrics_path, f"no {a.camera} video in this run")
    fps = float(videos[a.camera]["fps"])
    speed = a.speed if a.speed is not None else 1.0
    images = []
    for k in frames:
        path = os.path.join(a.run_dir, f"{a.camera}_frames", "%06d.png" % k)
        try:
            images.append(mpimg.imread(path))
        except (OSError, ValueError) as e:
            fail(path, getattr(e, "strerror", None) or str(e))
    h, w = images[0].shape[:2]
    fig, axes = plt.subplots(1, len(images), figsize=(3.2 * len(images) * w / h, 3.5))
    for ax, k, img in zip(axes if len(images) > 1 else [axes], frames, images):
        ax.imshow(img)
        ax.set_title("t = %.2f s" % (k * speed / fps), fontsize=10)
        ax.axis("off")
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    tmp = a.out + ".partial.png"
    try:
        fig.savefig(tmp, dpi=110)
        os.replace(tmp, a.out)
    except OSError as e:
        fail(a.out, e.strerror)


if __name__ == "__main__":
    main()
