#!/usr/bin/env python3
"""Plot the field-model study written by `magvine study field-models --out DIR`.

Left: worst relative error in B against time per evaluation for the exact cylinder, the point dipole and the
surface quadrature at increasing resolution (all against a fine quadrature). Right: worst relative error of the
dipole in B and in the gradient against distance from the magnet centre, with the 1 % and 5 % lines.

Usage: /usr/bin/python3 tools/plot_field_models.py DIR [--out DIR/field_models.png]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError as e:
        sys.exit(print(f"{path}: {e.strerror}", file=sys.stderr) or 2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    args = ap.parse_args()
    out = args.out or os.path.join(args.dir, "field_models.png")
    models = read_csv(os.path.join(args.dir, "field_models.csv"))
    dist = read_csv(os.path.join(args.dir, "field_model_distance.csv"))
    try:
        quad = [(float(r["ns_per_eval"]), float(r["max_rel_err_B"]), r["resolution"]) for r in models if r["model"] == "quadrature"]
        single = {r["model"]: (float(r["ns_per_eval"]), float(r["max_rel_err_B"])) for r in models if r["model"] != "quadrature"}
        d_mm = [1e3 * float(r["distance_m"]) for r in dist]
        eb = [100 * float(r["dipole_err_B"]) for r in dist]
        eg = [100 * float(r["dipole_err_G"]) for r in dist]
    except (KeyError, ValueError) as e:
        print(f"{args.dir}: malformed study CSV ({e})", file=sys.stderr)
        return 2

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    a.loglog([q[0] for q in quad], [q[1] for q in quad], "o-", color="tab:gray", label="surface quadrature (n_phi x n_z)")
    for t, e, lab in quad:
        a.annotate(lab, (t, e), textcoords="offset points", xytext=(4, 4), fontsize=7, color="tab:gray")
    a.loglog(*single["exact"], "s", color="tab:blue", ms=9, label="exact cylinder (closed form)")
    a.loglog(*single["dipole"], "^", color="tab:red", ms=9, label="point dipole")
    a.set_xlabel("time per evaluation [ns]")
    a.set_ylabel("worst relative error in B, 80-400 mm")
    a.set_title("Field models: error against runtime")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)

    b.semilogy(d_mm, eb, "o-", color="tab:red", label="dipole error in B")
    b.semilogy(d_mm, eg, "s--", color="tab:orange", label="dipole error in grad B")
    for level in (1, 5):
        b.axhline(level, color="k", lw=0.8, ls=":")
        b.text(d_mm[-1], level * 1.08, f"{level} %", ha="right", fontsize=8)
    b.set_xlabel("distance from the magnet centre [mm]")
    b.set_ylabel("worst relative error over directions [%]")
    b.set_title("Point dipole vs exact cylinder")
    b.grid(True, which="both", alpha=0.3)
    b.legend(fontsize=8)

    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=130)
    os.replace(tmp, out)
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
