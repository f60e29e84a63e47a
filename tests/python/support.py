"""What the Python tests share: the module (under ctest, which sets MAGVINE_REQUIRE_PYTHON, a broken import fails; run
by hand without the module, the tests skip), where the command line and the sources are, and a `magvine run`."""
import csv
import json
import os
import subprocess

import pytest

if os.environ.get("MAGVINE_REQUIRE_PYTHON"):
    import magvine
else:
    magvine = pytest.importorskip("magvine", reason="the Python module is not built (MAGVINE_WITH_PYTHON)")

CLI = os.environ.get("MAGVINE", "build/src/cli/magvine")
SRC = os.environ.get("MAGVINE_SOURCE_DIR", ".")
# What differs between two runs of one scene: the computing time.
TIMING = {"runtime_s", "real_time_factor"}
Y = os.path.join(SRC, "assets", "scenes", "y_bifurcation_fluid_vine.yaml")


def scene(name):
    """A bundled scene's path."""
    return os.path.join(SRC, "assets", "scenes", name)


def cli_run(path, out):
    """`magvine run PATH --out OUT`: its metrics.json and the rows of its tip_trajectory.csv."""
    subprocess.run([CLI, "run", str(path), "--out", str(out)], check=True, capture_output=True)
    with open(os.path.join(out, "metrics.json")) as f:
        metrics = json.load(f)
    with open(os.path.join(out, "tip_trajectory.csv")) as f:
        rows = list(csv.DictReader(f))
    return metrics, rows
