#!/usr/bin/env python3
"""The Python API's overhead, measured in one run against the C++ it calls (issue 32; docs/python.md, Speed):

1. Simulation.step on the demo scene (assets/scenes/bronchial_tree_platform.yaml): the wall time of the Python loop
   `while not sim.done: sim.step()` against the time spent inside the core's steps (Simulation.step_seconds, timed
   round Experiment::step with the GIL released); the overhead is what the binding adds per step (argument handling,
   the GIL, the lock). Repeated; the median.
3. Two simulations of the demo scene in two Python threads against the same two one after the other (wall time):
   the GIL is released in the steps, so on two cores the threads take about half as long.
2. magvine.field on 10^6 points round the thesis's EPM (100–300 mm, all directions, as bench_fields draws them)
   against bench_fields' BM_CylinderAxialFieldGradient (the same magnet, the core's batch evaluation), run here:
   into fresh arrays (which the kernel clears on first touch) and into reused ones (out=).

    PYTHONPATH=$(make -s python-path) /usr/bin/python3 tools/bench_python.py --bench build/tests/bench/bench_fields \
        --out build/bench_python.csv
"""
import argparse
import csv
import json
import statistics
import subprocess
import threading
import time

import numpy as np

import magvine


def step_overhead(scene, repeats):
    rows = []
    loaded = magvine.Scene(scene)
    for _ in range(repeats):
        sim = magvine.Simulation(loaded)
        start = time.perf_counter()
        while not sim.done:
            sim.step()
        wall = time.perf_counter() - start
        rows.append((sim.steps, wall, sim.step_seconds))
    return rows


def threads_ratio(scene, repeats):
    loaded = magvine.Scene(scene)

    def one():
        sim = magvine.Simulation(loaded)
        while not sim.done:
            sim.step()

    ratios = []
    for _ in range(repeats):
        start = time.perf_counter()
        one()
        one()
        serial = time.perf_counter() - start
        start = time.perf_counter()
        threads = [threading.Thread(target=one) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        ratios.append((time.perf_counter() - start) / serial)
    return ratios


def field_ratio(bench, magnets, points, repeats):
    rng = np.random.default_rng(42)
    x = rng.normal(size=(points, 3))
    x *= rng.uniform(0.1, 0.3, size=(points, 1)) / np.linalg.norm(x, axis=1, keepdims=True)
    python = []
    reused = []
    out = (np.empty((points, 3)), np.empty((points, 3, 3)))
    for _ in range(repeats):
        start = time.perf_counter()
        magvine.field(magnets, x)
        python.append((time.perf_counter() - start) / points)
        start = time.perf_counter()
        magvine.field(magnets, x, out=out)  # into arrays already written once (no fresh pages to clear)
        reused.append((time.perf_counter() - start) / points)
    out = subprocess.run([bench, "--benchmark_filter=BM_CylinderAxialFieldGradient$", "--benchmark_format=json",
                          f"--benchmark_repetitions={repeats}"], check=True, capture_output=True, text=True).stdout
    rates = [b["items_per_second"] for b in json.loads(out)["benchmarks"] if b.get("run_type") == "iteration"]
    return statistics.median(python), statistics.median(reused), statistics.median(1.0 / r for r in rates)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="assets/scenes/bronchial_tree_platform.yaml")
    parser.add_argument("--magnets", default="assets/magnets/epm_n52.yaml")
    parser.add_argument("--bench", default="build/tests/bench/bench_fields")
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default="bench_python.csv")
    args = parser.parse_args()

    runs = step_overhead(args.scene, args.repeats)
    overheads = [(wall - core) / core for _, wall, core in runs]
    steps = runs[0][0]
    per_step_core = statistics.median(core / n for n, _, core in runs)
    per_step_wall = statistics.median(wall / n for n, wall, _ in runs)
    py_point, py_reused, cpp_point = field_ratio(args.bench, args.magnets, args.points, args.repeats)
    threaded = threads_ratio(args.scene, max(1, args.repeats // 2))
    with open(args.out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["measure", "python", "cpp", "ratio"])
        w.writerow(["step_s (demo scene, median per step)", per_step_wall, per_step_core, per_step_wall / per_step_core])
        w.writerow(["field_s_per_point (1e6 points, fresh arrays)", py_point, cpp_point, py_point / cpp_point])
        w.writerow(["field_s_per_point (1e6 points, out= reused)", py_reused, cpp_point, py_reused / cpp_point])
        w.writerow(["two simulations: threads / one after the other (wall)", "", "", statistics.median(threaded)])
    print(f"Simulation.step on {args.scene} ({steps} steps): {1e3 * per_step_wall:.3f} ms per step from Python, "
          f"{1e3 * per_step_core:.3f} ms inside the core: overhead {100 * statistics.median(overheads):.2f} % "
          f"(runs: {', '.join(f'{100 * o:.2f}' for o in overheads)} %)")
    print(f"magvine.field on {args.points} points: {1e9 * py_point:.1f} ns per point into fresh arrays, "
          f"{1e9 * py_reused:.1f} into reused ones (out=); bench_fields BM_CylinderAxialFieldGradient "
          f"{1e9 * cpp_point:.1f} ns per point: ratios {py_point / cpp_point:.3f}, {py_reused / cpp_point:.3f}")
    print(f"two simulations in two threads: {', '.join(f'{r:.2f}' for r in threaded)} of the time one after the other")
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
