#!/usr/bin/python3
"""Plot the robot-mechanics validation written by `magvine validate --out DIR`.

Writes DIR/rod_convergence.png (tip error against time per equilibrium, one line per case, node counts marked),
DIR/vine_deflection.png (skin MVR bending angle against EPM distance, simulator and two-stage model, torque and
gradient setups, crease onset marked) and DIR/fluid_vine.png (magnetic-fluid vines, bounded law, with the thesis's
critical distance). A missing or malformed input gives one line on stderr and exit status 2.

    /usr/bin/python3 tools/plot_mechanics.py DIR
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError as e:
        print(f"plot_mechanics: {path}: {e.strerror}", file=sys.stderr)
        sys.exit(2)


def rod(dir_):
    rows = read(os.path.join(dir_, "rod_convergence.csv"))
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for case in dict.fromkeys(r["case"] for r in rows):
        pts = [r for r in rows if r["case"] == case and r["tip_error_rel_L"] not in ("nan", "")]
        t = [float(r["seconds"]) * 1e3 for r in pts]
        e = [float(r["tip_error_rel_L"]) * 100 for r in pts]
        ax.loglog(t, e, "o-", label=case)
        for r, x, y in zip(pts, t, e):
            ax.annotate(r["nodes"], (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8)
    ax.text(ax.get_xlim()[0], 1.05, " 1 % of L (acceptance)", fontsize=8, color="grey")
    ax.set_xlabel("time per equilibrium [ms] (one core)")
    ax.set_ylabel("tip error against the elastica [% of L]")
    ax.set_title("60 × 3 × 3 mm NdFeB–Dragon Skin rod: error against runtime\n(labels: nodes)", fontsize=10)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(dir_, "rod_convergence.png"), dpi=130)


def vine(dir_):
    rows = read(os.path.join(dir_, "vine_deflection.csv"))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    colours = {"1": "tab:blue", "6": "tab:orange", "12": "tab:green"}
    for ax, setup in zip(axes, ("torque", "gradient")):
        for p, c in colours.items():
            pts = [r for r in rows if r["setup"] == setup and r["pressure_kPa"] == p]
            d = [float(r["d_mm"]) for r in pts]
            ax.plot(d, [float(r["angle_deg"]) for r in pts], "-", color=c, label=f"{p} kPa simulator")
            ax.plot(d, [float(r["two_stage_angle_deg"]) for r in pts], "--", color=c, label=f"{p} kPa two-stage")
            creased = [float(r["d_mm"]) for r in pts if r["creased"] == "1"]
            stage2 = [float(r["d_mm"]) for r in pts if r["two_stage_stage"] == "2"]
            if creased:
                ax.axvline(max(creased), color=c, lw=0.6, ls="-")
            if stage2:
                ax.axvline(max(stage2), color=c, lw=0.6, ls="--")
        ax.set_title(f"{setup} setup (lines: crease onset)", fontsize=10)
        ax.set_xlabel("EPM distance d [mm] (h = 65 mm)")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("bending angle [deg]")
    axes[1].legend(fontsize=7)
    fig.suptitle("Skin MVR Ø8 mm, 80 mm, against gravity: simulator vs the thesis's two-stage model", fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(dir_, "vine_deflection.png"), dpi=130)


def fluid(dir_):
    rows = read(os.path.join(dir_, "fluid_vine.csv"))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for ax, law in zip(axes, ("bounded", "thesis")):
        for dia, c in (("4", "tab:blue"), ("5", "tab:orange"), ("7", "tab:green")):
            pts = [r for r in rows if r["law"] == law and r["diameter_mm"] == dia]
            pressures = sorted({r["pressure_kPa"] for r in pts}, key=float, reverse=True)
            for p, ls in zip(pressures, ("-", ":")):
                sel = [r for r in pts if r["pressure_kPa"] == p]
                ax.plot([float(r["d_mm"]) for r in sel], [float(r["angle_deg"]) for r in sel], ls, color=c,
                        label=f"Ø{dia} mm, {float(p):.1f} kPa")
        ax.axvline(160, color="grey", ls="--", lw=0.8)
        ax.text(162, 5, "thesis ≈160 mm", fontsize=8, color="grey")
        ax.set_title(f"{law} fluid law", fontsize=10)
        ax.set_xlabel("EPM distance d [mm]")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("bending angle [deg]")
    axes[0].legend(fontsize=7)
    fig.suptitle("Magnetic-fluid vines, 50 mm, vertical against gravity (thesis 5.6.1: 52°, 59°, 51°)", fontsize=11)
    fig.tight_layout()
    fig.savefig(os.path.join(dir_, "fluid_vine.png"), dpi=130)


def main():
    if len(sys.argv) != 2:
        print("usage: plot_mechanics.py DIR", file=sys.stderr)
        sys.exit(2)
    try:
        rod(sys.argv[1])
        vine(sys.argv[1])
        fluid(sys.argv[1])
    except (KeyError, ValueError) as e:
        print(f"plot_mechanics: malformed input: {e}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
