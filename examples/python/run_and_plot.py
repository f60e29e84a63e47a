"""Run a scene step by step from Python and plot it: the body every half second seen from above, the tip's path, and
the wall's largest normal force against time (docs/python.md).

    PYTHONPATH=$(make -s python-path) /usr/bin/python3 examples/python/run_and_plot.py \
        assets/scenes/y_bifurcation_fluid_vine.yaml --out run.png
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import magvine  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="assets/scenes/y_bifurcation_fluid_vine.yaml")
    parser.add_argument("--out", default="run.png", help="the figure (PNG)")
    parser.add_argument("--every", type=float, default=0.5, help="draw the body every so many seconds")
    args = parser.parse_args()

    sim = magvine.Simulation(args.scene)
    times, tips, forces, shapes = [], [], [], []
    next_shape = 0.0
    while not sim.done:
        sim.step()
        s = sim.state
        times.append(s.time)
        tips.append(s.tip_position)
        forces.append(s.max_wall_normal)
        if s.time >= next_shape - 1e-9:
            shapes.append((s.time, s.nodes))
            next_shape += args.every
    progress = sim.progress  # along the path to the target (None without one)
    metrics = sim.finish()
    tips = np.array(tips) * 1e3

    fig, (top, force) = plt.subplots(1, 2, figsize=(11, 4.5))
    colours = plt.cm.viridis(np.linspace(0, 1, len(shapes)))
    for (t, nodes), c in zip(shapes, colours):
        top.plot(nodes[:, 0] * 1e3, nodes[:, 1] * 1e3, color=c, lw=1.5, label=f"{t:.1f} s" if len(shapes) < 12 else None)
    top.plot(tips[:, 0], tips[:, 1], "k:", lw=1, label="tip path")
    if sim.target is not None:
        top.plot(*(sim.target[:2] * 1e3), "r*", ms=12, label="target")
    if sim.path is not None:
        top.plot(sim.path[:, 0] * 1e3, sim.path[:, 1] * 1e3, color="0.6", lw=0.8, ls="--", label="path to target")
    top.set_aspect("equal")
    top.set_xlabel("x [mm]")
    top.set_ylabel("y [mm]")
    top.set_title(f"{'reached' if metrics['success'] else 'did not reach'} the target (progress {progress:.2f})"
                  if progress is not None else "the body")
    top.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    force.plot(times, forces)
    force.set_xlabel("time [s]")
    force.set_ylabel("largest wall normal force on a node [N]")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"{args.out}: {len(times)} steps, success {metrics['success']}, max wall normal "
          f"{metrics['max_wall_normal_N']:.3f} N, {metrics['simulated_s']:.2f} s simulated")


if __name__ == "__main__":
    main()
