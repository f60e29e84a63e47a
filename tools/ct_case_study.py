#!/usr/bin/python3
"""The CT case study (issue 31, item 5; thesis 5.6.5 and its table 5.2): for each Med-MPD patient, a vine navigated
from the trachea to the stop from which a straight needle reaches the patient's nodule, then the puncture; perturbed
repeats with and without breathing, as one table.

    /usr/bin/python3 tools/ct_case_study.py SEGMENTATIONS_DIR --out DIR [--magvine BIN] [--repeats 4] [--jobs 2]
        [--patients 1,2,3,4,5] [--diameter 3] [--needle 100] [--max-angle DEG] [--start K|nearest]
        [--no-breathing] [--guidance oracle|camera] [--figure CASE[,CASE...]]

SEGMENTATIONS_DIR holds Patient1..5/ (bronchialTree.nii.gz, target.txt), e.g. ../shared/airways/segmentations.
For each patient and breathing setting it writes DIR/scenes/<case>.yaml (the segmentation imported by the scene,
the base 15 mm down the airway graph's root, the nodule from target.txt, the generation-4 scene's fluid vine at the
given diameter, boost (`boost_line`) and recovery; the supine patient's gravity, posterior, is −y in the scans'
RAS frame) and runs `magvine trials --keep-runs` on it into DIR/<case>/. Then DIR/case_study.csv and
DIR/case_study.md: per case the stop (branch, generation, needle length, the needle's planned turn from the branch,
and how far from the nodule's centre a tip that cannot turn points from the best stop the tool fits to), reached k/N,
the generation reached (median), the everted length and the time to the stop (mean over those that reached it),
needle pushed (the puncture phase ran), the tip's angle to the nodule after aiming (median), punctured (the needle
passed the wall's puncture depth) and biopsy k/N, the needle tip's distance to the nodule (median over the runs that
pushed it), the largest wall force (median over the runs, and the largest), and the failures' reasons. --max-angle
sets the planner's largest turn (degrees; the scene's default, 60, otherwise); --start K|nearest stops at the node
nearest the dataset's start pose K (startK.txt; nearest: the one nearest the nodule) instead of the planner's
choice; --guidance camera steers by the tip camera and the plan instead of the tip's true position
(docs/experiments.md, camera guidance). --figure CASE[,CASE...] (e.g. patient1) runs each case's scene once,
unperturbed, with the tip camera filmed, and draws DIR/<case>_frames.png: the tip camera at each branch point on the
way (the first frame in each new branch) and at the end (the puncture, with the needle drawn beside the lens). A
missing input gives one line on stderr and exit status 2.
"""
import argparse
import csv
import functools
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tool_errors import input_error  # noqa: E402

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

SCENE = """# The CT case study's scene for {label} (tools/ct_case_study.py writes it).
units: {{length: mm, pressure: kPa}}
seed: {seed}
anatomy:
  segmentation: {segmentation}
{breathing}robot:
  kind: vine
  length: 5
  diameter: {diameter}
  pressure: 35
  wall: {{thickness: 0.038, youngs_modulus: 10000, density: 1100, strength: 2900}}
  fill: {{kind: magnetic_fluid, volume_fraction: 0.23}}
  base: {{entry: 15}}
growth: {{yield_pressure: 20, retraction_pressure: 5}}
magnets:
  - {{kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, position: [0, 400, 0], axis: [0, 1, 0]}}
control:
  pressure: [[0, 35]]
  navigator:
    target: {{nodule: {target}{limits}, needle: {{length: {needle}}}}}
    magnet: 0
    distance: 110
{boost}{guidance}    recover: {{retries: 3}}
simulation: {{duration: 40, dt: 0.02, gravity: [0, -9.81, 0]}}
"""


fail = functools.partial(input_error, "ct_case_study")


def case_name(patient, breathing):
    """A case's folder and scene name: patientN, or patientN_breathing."""
    return f"patient{patient}" + ("_breathing" if breathing else "")


def number(text):
    try:
        return float(text)
    except ValueError:
        return None


def summarise(case, runs_dir, rows):
    """One row of the table from a case's trials.csv rows and its runs' metrics.json."""
    n = len(rows)
    reached = [r for r in rows if r["success"] == "1"]
    generations = []
    walls = []
    pushed = 0
    punctured = 0
    stop = {}
    aims = []
    for r in rows:
        path = os.path.join(runs_dir, f"{r['target']}_r{r['repeat']}", "metrics.json")
        try:
            with open(path) as f:
                m = json.load(f)
        except (OSError, ValueError):
            continue
        if m.get("generation_reached") is not None:
            generations.append(m["generation_reached"])
        if m.get("max_wall_normal_N") is not None:
            walls.append(m["max_wall_normal_N"])
        b = m.get("biopsy") or {}
        pushed += bool(b.get("needle_pushed"))
        punctured += bool(b.get("punctured"))
        if b.get("aim_angle_deg") is not None:
            aims.append(b["aim_angle_deg"])
        if not stop and b.get("stop_branch"):
            stop = b
    to_nodule = [number(r["needle_to_nodule_m"]) for r in rows if number(r["needle_to_nodule_m"]) is not None]
    biopsies = sum(r["biopsy"] == "1" for r in rows)
    mean = lambda xs: statistics.mean(xs) if xs else None  # noqa: E731
    return {
        "case": case,
        "stop_branch": stop.get("stop_branch", ""),
        "stop_generation": stop.get("stop_branch", "").count("-") if stop else "",
        "needle_mm": round(1e3 * stop["needle_m"], 1) if stop else "",
        "needle_angle_deg": round(stop["needle_angle_deg"], 1) if stop.get("needle_angle_deg") is not None else "",
        "given_stop_distance_mm": round(1e3 * stop["given_stop_distance_m"], 1)
        if stop.get("given_stop_distance_m") is not None else "",
        "needle_crosses_airway": int(stop["needle_crosses_airway"]) if stop.get("needle_crosses_airway") is not None
        else "",
        # over every node the tool fits to, not the stop's own (older runs' metrics lack it: left blank)
        "best_straight_miss_mm": round(1e3 * stop["best_straight_miss_m"], 1)
        if stop.get("best_straight_miss_m") is not None else "",
        "aim_angle_deg": round(statistics.median(aims), 1) if aims else "",
        "runs": n,
        "reached": len(reached),
        "generation_median": statistics.median(generations) if generations else "",
        "everted_mm": round(1e3 * mean([float(r["everted_length_m"]) for r in reached]), 1) if reached else "",
        "time_s": round(mean([float(r["time_to_target_s"]) for r in reached]), 2) if reached else "",
        "needle_pushed": pushed,
        "punctured": punctured,
        "biopsy": biopsies,
        "needle_to_nodule_mm": round(1e3 * statistics.median(to_nodule), 1) if to_nodule else "",
        "wall_N_median": round(statistics.median(walls), 3) if walls else "",
        "wall_N_max": round(max(walls), 3) if walls else "",
        # One line per failure: a reason's own semicolons become commas (the list is split on "; ").
        "failures": "; ".join(f"r{r['repeat']}: {r['reason'].replace(';', ',')}" for r in rows if r["reason"]),
    }


def numbers(path, count):
    """The `count` numbers of a planning problem's text file (target.txt: 3, startK.txt: 16)."""
    try:
        with open(path) as f:
            values = [float(x) for x in f.read().split()]
    except (OSError, ValueError) as e:
        fail(path, f"unreadable as numbers ({e})")
    if len(values) != count:
        fail(path, f"needs {count} numbers")
    return values


def start_pose(folder, which):
    """The path of the patient's start pose file: startK.txt, or for "nearest" the one whose position (the 4x4 pose's
    translation, mm) lies nearest the nodule of target.txt."""
    if which != "nearest":
        path = os.path.join(folder, f"start{which}.txt")
        if not os.path.exists(path):
            fail(path, "missing")
        return path
    nodule = numbers(os.path.join(folder, "target.txt"), 3)
    best, best_d = "", float("inf")
    for k in range(1, 100):
        path = os.path.join(folder, f"start{k}.txt")
        if not os.path.exists(path):
            break
        m = numbers(path, 16)
        d = sum((m[4 * i + 3] - nodule[i]) ** 2 for i in range(3)) ** 0.5
        if d < best_d:
            best, best_d = path, d
    if not best:
        fail(os.path.join(folder, "start1.txt"), "missing")
    return best


def boost_line(diameter):
    """The navigator's pressure boost for a held tip: 45 kPa up to Ø3 mm, 42 up to Ø4 mm (the generation-4 scene's);
    none above Ø4 mm, where the 38 µm film bursts not far above the 35 kPa it grows at (35.7 kPa at Ø5 mm,
    `burst_pressure` in src/robot/src/vine.cpp; magvine refuses a boost above it)."""
    if diameter <= 3.0:
        return "    boost_pressure: 45\n"
    if diameter <= 4.0:
        return "    boost_pressure: 42\n"
    return ""


def figure(magvine, scene, out_dir, case):
    """The tip camera at each branch point and at the end of one unperturbed run of `scene`."""
    fps = 10.0
    filmed = os.path.join(out_dir, "scenes", case + "_filmed.yaml")
    with open(scene) as f, open(filmed, "w") as g:
        g.write(f.read() + "outputs:\n  video:\n    - {camera: tip, size: [240, 240], fov: 120, lens: fisheye, "
                f"fps: {fps:g}, frames: true}}\n")
    run = os.path.join(out_dir, case + "_run")
    subprocess.run([magvine, "run", filmed, "--out", run], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    trajectory = os.path.join(run, "tip_trajectory.csv")
    frames_dir = os.path.join(run, "tip_frames")
    if not os.path.exists(trajectory) or not os.path.isdir(frames_dir):
        fail(run, "the filmed run left no trajectory or frames (it failed: see its metrics.json)")
    with open(trajectory, newline="") as f:
        rows = list(csv.DictReader(f))
    with open(os.path.join(run, "metrics.json")) as f:
        biopsy = json.load(f).get("biopsy") or {}
    stop = biopsy.get("stop_branch", "")
    # The first time the tip is in each branch on the way to the stop (a junction just passed), the trachea left out.
    picks = []
    seen = set()
    for r in rows:
        name = r["branch"]
        on_way = name != "0" and (stop + "-").startswith(name + "-")
        if on_way and name not in seen:
            seen.add(name)
            picks.append((float(r["t_s"]), name))
    last = len(os.listdir(frames_dir)) - 1
    needle_out = biopsy.get("needle_pushed") and (biopsy.get("max_reaction_N") or 0.0) > 0.0  # it met the tissue
    picks = picks[-7:] + [(last / fps, "end, needle out" if needle_out else "end")]
    fig, axes = plt.subplots(1, len(picks), figsize=(2.4 * len(picks), 2.8))
    for ax, (t, name) in zip(axes if len(picks) > 1 else [axes], picks):
        k = min(last, int(round(t * fps)))
        ax.imshow(mpimg.imread(os.path.join(frames_dir, "%06d.png" % k)))
        ax.set_title(f"{name}\n{t:.1f} s", fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, case + "_frames.png"), dpi=90)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("segmentations")
    p.add_argument("--out", required=True)
    p.add_argument("--magvine", default=os.path.join(os.path.dirname(__file__), "..", "build", "src", "cli", "magvine"))
    p.add_argument("--repeats", type=int, default=4)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--patients", default="1,2,3,4,5")
    p.add_argument("--diameter", type=float, default=3.0, help="the vine's diameter [mm]")
    p.add_argument("--needle", type=float, default=100.0, help="the needle's length and the planner's limit [mm]")
    p.add_argument("--max-angle", type=float, default=None,
                   help="the planner's largest turn of the needle from the branch [degrees] (default: the scene's)")
    p.add_argument("--start", default="",
                   help="stop at the dataset's start pose K (startK.txt), or the one nearest the nodule (nearest), "
                        "instead of the planner's choice")
    p.add_argument("--guidance", choices=["oracle", "camera"], default="oracle",
                   help="the navigator's guidance: the tip's true position, or the tip camera and the plan")
    p.add_argument("--no-breathing", action="store_true")
    p.add_argument("--figure", default="", help="cases to film and draw, comma-separated (e.g. patient1,patient2)")
    a = p.parse_args()
    if a.start and a.max_angle is not None:
        fail("--max-angle", "a given start (--start) is taken as given: no planner limit applies to it")
    if not os.access(a.magvine, os.X_OK):
        fail(a.magvine, "not an executable magvine (build it, or give --magvine)")
    # The cases to film, checked before the trials run: patientN or patientN_breathing of the patients run here.
    try:
        patients = [int(x) for x in a.patients.split(",")]
    except ValueError:
        fail("--patients", f"{a.patients!r} is not a comma list of patient numbers")
    breathings = [False] if a.no_breathing else [False, True]
    planned = [case_name(p, b) for p in patients for b in breathings]
    figures = [c.strip() for c in a.figure.split(",") if c.strip()]
    for case in figures:
        if case not in planned:
            fail("--figure", f"{case} is not a case of this study ({', '.join(planned)})")
    os.makedirs(os.path.join(a.out, "scenes"), exist_ok=True)
    cases = []
    for patient in patients:
        folder = os.path.abspath(os.path.join(a.segmentations, f"Patient{patient}"))
        for f in ("bronchialTree.nii.gz", "target.txt"):
            if not os.path.exists(os.path.join(folder, f)):
                fail(os.path.join(folder, f), "missing")
        start = start_pose(folder, a.start) if a.start else ""
        for breathing in breathings:
            case = case_name(patient, breathing)
            scene = os.path.join(a.out, "scenes", case + ".yaml")
            with open(scene, "w") as f:
                f.write(SCENE.format(
                    label=f"Med-MPD patient {patient}" + (", breathing" if breathing else ""),
                    seed=patient, segmentation=os.path.join(folder, "bronchialTree.nii.gz"),
                    breathing="  breathing: {period: 4}\n" if breathing else "", diameter=a.diameter,
                    target=os.path.join(folder, "target.txt"), needle=a.needle,
                    limits=(f", stop: {start}" if start else
                            f", max_needle: {a.needle:g}"
                            + (f", max_angle: {a.max_angle:g}" if a.max_angle is not None else "")),
                    boost=boost_line(a.diameter),
                    guidance="    guidance: {mode: camera, frames: false}\n" if a.guidance == "camera" else ""))
            out = os.path.join(a.out, case)
            print(f"ct_case_study: {case} ...", flush=True)
            r = subprocess.run([a.magvine, "trials", scene, "--repeats", str(a.repeats), "--jobs", str(a.jobs),
                                "--keep-runs", "--out", out], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
            trials = os.path.join(out, "trials.csv")
            if r.returncode != 0 or not os.path.exists(trials):
                # No trials ran: the reason in the row's failures; "none" for the stop where the planner found none.
                said = r.stderr.strip()
                reason = said.splitlines()[-1].replace(";", ",") if said else f"magvine trials exited {r.returncode}"
                no_stop = "no stop reaches the nodule" in reason
                cases.append({"case": case, "runs": 0, "stop_branch": "none" if no_stop else "",
                              "stop_generation": "—" if no_stop else "", "failures": reason})
                continue
            with open(trials, newline="") as f:
                rows = list(csv.DictReader(f))
            cases.append(summarise(case, os.path.join(out, "runs"), rows))
    columns = ["case", "stop_branch", "stop_generation", "needle_mm", "needle_angle_deg", "best_straight_miss_mm",
               "given_stop_distance_mm", "needle_crosses_airway", "runs",
               "reached", "generation_median",
               "everted_mm", "time_s", "needle_pushed", "aim_angle_deg", "punctured", "biopsy", "needle_to_nodule_mm",
               "wall_N_median",
               "wall_N_max", "failures"]
    with open(os.path.join(a.out, "case_study.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for c in cases:
            w.writerow({k: c.get(k, "") for k in columns})
    with open(os.path.join(a.out, "case_study.md"), "w") as f:
        f.write("| case | stop (generation) | needle [mm] | needle's turn from the branch [deg] | "
                "a tip that cannot turn misses by, at best [mm] | reached | generation reached | everted [mm] | "
                "time [s] | "
                "needle pushed | tip's angle to the nodule [deg] | punctured | biopsy | needle tip to nodule [mm] | "
                "peak wall force, median / largest [N] |\n")
        f.write("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
        for c in cases:
            n = c.get("runs", 0)
            f.write(f"| {c['case']} | {c.get('stop_branch', '')} ({c.get('stop_generation', '')}) | "
                    f"{c.get('needle_mm', '')} | {c.get('needle_angle_deg', '')} | "
                    f"{c.get('best_straight_miss_mm', '')} | "
                    f"{c.get('reached', 0)}/{n} | {c.get('generation_median', '')} | "
                    f"{c.get('everted_mm', '')} | {c.get('time_s', '')} | {c.get('needle_pushed', 0)}/{n} | "
                    f"{c.get('aim_angle_deg', '')} | "
                    f"{c.get('punctured', 0)}/{n} | "
                    f"{c.get('biopsy', 0)}/{n} | {c.get('needle_to_nodule_mm', '')} | "
                    f"{c.get('wall_N_median', '')} / {c.get('wall_N_max', '')} |\n")
        f.write("\nFailures:\n\n")
        for c in cases:
            for line in filter(None, c.get("failures", "").split("; ")):
                f.write(f"- {c['case']} {line}\n")
    print(f"ct_case_study: {os.path.join(a.out, 'case_study.md')}")
    for case in figures:
        figure(a.magvine, os.path.join(a.out, "scenes", case + ".yaml"), a.out, case)


if __name__ == "__main__":
    main()
