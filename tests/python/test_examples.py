"""examples/python run as a user runs them (docs/python.md): each writes its figure, the scripted policy reaches the
Y phantom's target where the random one does not, and the threaded sweep gives each run's metrics alone."""
import importlib.util
import os
import subprocess
import sys

import pytest

from support import SRC, magvine  # the module, or a skip
pytest.importorskip("matplotlib", reason="python3-matplotlib is not installed")

EXAMPLES = os.path.join(SRC, "examples", "python")


def example(name, *args, cwd):
    env = dict(os.environ)
    done = subprocess.run([sys.executable, os.path.join(EXAMPLES, name), *args], cwd=cwd, env=env,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done.stdout


def load(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(EXAMPLES, name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_run_and_plot(tmp_path):
    out = tmp_path / "run.png"
    text = example("run_and_plot.py", os.path.join(SRC, "assets/scenes/y_bifurcation_fluid_vine.yaml"), "--out",
                   str(out), cwd=SRC)
    assert out.stat().st_size > 10_000 and "success True" in text


def test_field_map(tmp_path):
    out = tmp_path / "field.png"
    example("field_map.py", os.path.join(SRC, "assets/magnets/epm_n52.yaml"), "--out", str(out), "--cells", "60",
            cwd=SRC)
    assert out.stat().st_size > 10_000


def test_the_scripted_policy_reaches_the_target_and_the_random_one_does_not():
    policies = load("policies")
    env = magvine.NavigationEnv(os.path.join(SRC, "assets/scenes/y_bifurcation_fluid_vine.yaml"), max_steps=120)
    scripted, info = policies.episode(env, policies.scripted, 0)
    assert info["success"], info
    random, info = policies.episode(env, None, 0)
    assert not info["success"] and random < scripted


def test_the_threaded_sweep(tmp_path):
    pytest.importorskip("yaml", reason="python3-yaml is not installed")
    text = example("sweep.py", os.path.join(SRC, "assets/scenes/y_bifurcation_fluid_vine.yaml"), "--out",
                   str(tmp_path), "--y", "110", "200", "--threads", "2", cwd=SRC)
    assert (tmp_path / "sweep.png").exists() and "reached the target" in text
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(lines) == 3
    # The y = 110 mm run is the bench scene itself: the thread pool gives its metrics as one run alone does.
    alone = magvine.run(os.path.join(SRC, "assets/scenes/y_bifurcation_fluid_vine.yaml"))
    row = dict(zip(lines[0].split(","), lines[1].split(",")))
    assert float(row["max_wall_normal_N"]) == alone["max_wall_normal_N"]
