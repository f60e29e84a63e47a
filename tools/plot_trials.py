#!/usr/bin/python3
"""Plot a trial batch written by `magvine trials` (trials.csv and summary.csv in its folder).

Left: success rate per target, with successes/trials on each bar. Right: every trial's time to target
(successes as dots, failures as crosses at the run's end, jittered sideways so repeats do not hide each
other) with the mean and SD over the successes, as thesis table 5.2 reports them. A missing or malformed
input gives one line on stderr, exit status 2 and no PNG.

    /usr/bin/python3 tools/plot_trials.py TRIALS_DIR --out PNG [--title T]
"""
import argparse
import csv
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def fail(path, problem):
    """Report a bad input or output file in one line and exit with status 2."""
    print(f"plot_trials: {path}: {problem}", file=sys.stderr)
    sys.exit(2)


def read_rows(path, needed):
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        fail(path, e.strerror)
    if not rows:
        fail(path, "no rows")
    missing = [k for k in needed if k not in rows[0]]
    if missing:
        fail(path, "header lacks " + ",".join(missing))
    return rows


def number(path, row, key, allow_empty=False):
    text = row[key]
    if allow_empty and text in ("", "nan"):
        return float("nan")
    try:
        return float(text)
    except ValueError:
        fail(path, f"{key} '{text}' is not a number")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("trials_dir")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default="")
    a = p.parse_args()
    summary_path = os.path.join(a.trials_dir, "summary.csv")
    trials_path = os.path.join(a.trials_dir, "trials.csv")
    summary = read_rows(summary_path, ("target", "successes", "trials", "success_rate", "mean_time_s", "sd_time_s"))
    trials = read_rows(trials_path, ("target", "success", "time_to_target_s", "runtime_s"))
    targets = [r["target"] for r in summary]

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    x = np.arange(len(targets))
    rate = [100 * number(summary_path, r, "success_rate") for r in summary]
    ax.bar(x, rate, color="tab:green", alpha=0.75)
    for k, r in enumerate(summary):
        ax.annotate(f"{r['successes']}/{r['trials']}", (k, rate[k]), ha="center", va="bottom", fontsize=9)
    ax.set_xticks(x, targets, rotation=30, ha="right")
    ax.set_ylim(0, 112)
    ax.set_ylabel("success rate [%]")
    ax.set_xlabel("target branch")
    ax.grid(axis="y", alpha=0.3)

    rng = np.random.default_rng(0)  # the sideways jitter only; the same picture every time
    for row in trials:
        if row["target"] not in targets:
            fail(trials_path, f"target {row['target']} is not in summary.csv")
        k = targets.index(row["target"])
        ok = number(trials_path, row, "success") == 1
        t = number(trials_path, row, "time_to_target_s", allow_empty=True)
        dx = rng.uniform(-0.15, 0.15)
        if ok:
            ax2.plot(k + dx, t, "o", color="tab:blue", ms=5, alpha=0.8)
        else:
            ax2.plot(k + dx, 0, "x", color="tab:red", ms=7)
    for k, r in enumerate(summary):
        mean = number(summary_path, r, "mean_time_s", allow_empty=True)
        sd = number(summary_path, r, "sd_time_s", allow_empty=True)
        if np.isfinite(mean):
            ax2.errorbar(k + 0.3, mean, yerr=sd if np.isfinite(sd) else None, fmt="s", color="black", capsize=4, ms=5)
    ax2.plot([], [], "o", color="tab:blue", label="trial: time to target")
    ax2.plot([], [], "x", color="tab:red", label="trial: failed (at 0)")
    ax2.errorbar([], [], yerr=[], fmt="s", color="black", capsize=4, label="mean ± SD of the successes")
    ax2.set_xticks(x, targets, rotation=30, ha="right")
    ax2.set_ylabel("time to target [s]")
    ax2.set_xlabel("target branch")
    ax2.set_ylim(bottom=0)
    ax2.legend(fontsize=8, loc="lower right")
    ax2.grid(axis="y", alpha=0.3)
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    tmp = a.out + ".partial.png"
    try:
        fig.savefig(tmp, dpi=130)
        os.replace(tmp, a.out)
    except OSError as e:
        fail(a.out, e.strerror)


if __name__ == "__main__":
    main()
