"""|B| and |∇B| of a magnets file on a plane through its magnet, from magvine.field on a grid (docs/python.md).

    PYTHONPATH=$(make -s python-path) /usr/bin/python3 examples/python/field_map.py assets/magnets/epm_n52.yaml \
        --out field_map.png
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as colors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import magvine  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("magnets", nargs="?", default="assets/magnets/epm_n52.yaml")
    parser.add_argument("--out", default="field_map.png")
    parser.add_argument("--half-width", type=float, default=0.25, help="half the plane's side [m] (x–z plane, y = 0)")
    parser.add_argument("--cells", type=int, default=300, help="grid points per side")
    args = parser.parse_args()

    u = np.linspace(-args.half_width, args.half_width, args.cells)
    x, z = np.meshgrid(u, u)
    points = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    b, g = magvine.field(args.magnets, points)
    b_mt = np.linalg.norm(b, axis=1).reshape(x.shape) * 1e3
    g_tm = np.linalg.norm(g, axis=(1, 2)).reshape(x.shape)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, value, label in ((axes[0], b_mt, "|B| [mT]"), (axes[1], g_tm, "|∇B| (Frobenius) [T/m]")):
        shown = np.clip(value, np.percentile(value, 1), np.percentile(value, 95))  # inside the magnet is off scale
        im = ax.pcolormesh(x * 1e3, z * 1e3, shown, norm=colors.LogNorm(), shading="auto")
        fig.colorbar(im, ax=ax, label=label)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("z [mm]")
    axes[0].streamplot(x * 1e3, z * 1e3, b[:, 0].reshape(x.shape), b[:, 2].reshape(x.shape), color="w",
                       linewidth=0.5, density=1.2)
    fig.suptitle(f"{args.magnets}: the plane y = 0, {points.shape[0]} points")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"{args.out}: |B| {b_mt.min():.3g}–{b_mt.max():.3g} mT on the plane")


if __name__ == "__main__":
    main()
