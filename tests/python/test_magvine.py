"""`import magvine` against the command line it mirrors (docs/python.md): the same metrics to the last bit for
bundled scenes, the same mesh report, the same one-line error; the field against a point dipole's closed form.
Run by ctest (tests/CMakeLists.txt) with PYTHONPATH at the built module and MAGVINE at the CLI."""
import csv
import json
import math
import os
import subprocess
import threading

import numpy as np
import pytest

from support import CLI, SRC, TIMING, cli_run, magvine  # the module, or a skip



@pytest.mark.parametrize("scene", ["y_bifurcation_fluid_vine.yaml", "bronchial_tree_navigator.yaml",
                                   "constriction_catheter.yaml"])
def test_run_gives_the_command_lines_metrics(scene, tmp_path):
    path = os.path.join(SRC, "assets", "scenes", scene)
    ours = magvine.run(path, out=tmp_path / "py")
    theirs, _ = cli_run(path, tmp_path / "cli")
    assert set(ours) == set(theirs)
    for key in set(ours) - TIMING:
        assert ours[key] == theirs[key], key  # to the last bit: the same doubles through the same JSON


def test_a_scene_as_a_dict_runs_as_its_file(tmp_path):
    # The dict with the scene file's keys (here the file's own content, through JSON) gives the file's metrics.
    yaml = pytest.importorskip("yaml", reason="python3-yaml is not installed")
    path = os.path.join(SRC, "assets", "scenes", "y_bifurcation_fluid_vine.yaml")
    with open(path) as f:
        scene = yaml.safe_load(f)
    ours = magvine.run(scene)
    theirs = magvine.run(path)
    for key in set(theirs) - TIMING - {"scene"}:
        assert ours[key] == theirs[key], key


def test_a_bad_scene_raises_value_error_with_the_command_lines_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    with open(os.path.join(SRC, "assets", "scenes", "y_bifurcation_fluid_vine.yaml")) as f:
        bad.write_text(f.read().replace("pressure: 35", "pressure: -35", 1))
    with pytest.raises(ValueError) as error:
        magvine.run(bad)
    cli = subprocess.run([CLI, "run", str(bad), "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert cli.returncode == 2
    assert str(error.value) in cli.stderr


def test_mesh_check_is_the_command_lines_report(tmp_path):
    stl = tmp_path / "tube.stl"
    subprocess.run([CLI, "phantom", "tube", "--out", str(stl)], check=True, capture_output=True)
    cli = subprocess.run([CLI, "mesh", "check", str(stl), "--json"], check=True, capture_output=True, text=True)
    assert magvine.mesh_check(str(stl)) == json.loads(cli.stdout)


def test_field_of_a_point_dipole_is_its_closed_form(tmp_path):
    # B = μ0/(4π) (3 (m·r̂) r̂ − m) / r³ at points round a 970 A·m² dipole at the origin along z (the EPM's moment).
    magnets = tmp_path / "dipole.yaml"
    magnets.write_text("units: {length: mm}\nmagnets:\n  - {kind: dipole, position: [0, 0, 0], moment: [0, 0, 970]}\n")
    rng = np.random.default_rng(3)
    points = rng.normal(size=(50, 3))
    points *= (0.1 + 0.1 * rng.random((50, 1))) / np.linalg.norm(points, axis=1, keepdims=True)
    b, g = magvine.field(str(magnets), points)
    assert b.shape == (50, 3) and g.shape == (50, 3, 3)
    m = np.array([0.0, 0.0, 970.0])
    for x, bx in zip(points, b):
        r = np.linalg.norm(x)
        u = x / r
        expected = 1e-7 * (3 * np.dot(m, u) * u - m) / r**3
        assert np.allclose(bx, expected, rtol=1e-12, atol=0.0)
    # The gradient against central differences of B (step 1 µm; error ~ (h/r)² ≈ 1e-10 of G).
    h = 1e-6
    x = points[:1]
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        bp, _ = magvine.field(str(magnets), x + e)
        bm, _ = magvine.field(str(magnets), x - e)
        assert np.allclose(g[0][:, k], (bp[0] - bm[0]) / (2 * h), rtol=1e-6, atol=1e-12)
    with pytest.raises(ValueError):
        magvine.field(str(magnets), np.zeros((4, 2)))
    # Into the caller's arrays: the same numbers, the same objects back; arrays of the wrong kind refused.
    out = (np.zeros((50, 3)), np.zeros((50, 3, 3)))
    back = magvine.field(str(magnets), points, out=out)
    assert back[0] is out[0] and back[1] is out[1]
    np.testing.assert_array_equal(out[0], b)
    np.testing.assert_array_equal(out[1], g)
    for bad in [(out[0],), (out[0].astype(np.float32), out[1]), (np.zeros((49, 3)), out[1]),
                (out[0], np.zeros((50, 3, 3))[:, ::-1])]:
        with pytest.raises(ValueError, match="out"):
            magvine.field(str(magnets), points, out=bad)


def test_runs_in_threads_give_the_same_metrics(tmp_path):
    # Two runs at once in two Python threads (the GIL released while they compute): the same metrics as one alone.
    path = os.path.join(SRC, "assets", "scenes", "y_bifurcation_fluid_vine.yaml")
    alone = magvine.run(path)
    results = [None, None]

    def one(i):
        results[i] = magvine.run(path)

    threads = [threading.Thread(target=one, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        assert {k: v for k, v in r.items() if k not in TIMING} == {k: v for k, v in alone.items() if k not in TIMING}


def test_phantom_is_the_command_lines_phantom(tmp_path):
    # The same parameters by keyword (metadata names) and by option (--gap-mm): the same mesh file, graph and metadata.
    stl = tmp_path / "py.stl"
    ours = magvine.phantom("constriction", out=stl, gap_mm=2.5, constriction_x_mm=40)
    subprocess.run([CLI, "phantom", "constriction", "--gap-mm", "2.5", "--constriction-x-mm", "40", "--out",
                    str(tmp_path / "cli.stl")], check=True, capture_output=True)
    assert stl.read_bytes() == (tmp_path / "cli.stl").read_bytes()
    with open(tmp_path / "cli.meta.json") as f:
        assert ours["metadata"] == json.load(f)
    assert ours["metadata"]["parameters"]["gap_mm"] == 2.5
    assert ours["triangles"].shape[1] == 3 and ours["triangles"].max() < len(ours["vertices"])
    # A keyword reaches the generator: a Y phantom asked for daughters at 25° has them there (its ground-truth graph:
    # each daughter's centreline from its first node to its last against the parent's +x axis; the graph's nodes are
    # exact, so 0.5° is the polyline's own rounding).
    y = magvine.phantom("y_bifurcation", branch_angle_deg=25)
    nodes = np.array([n["position"] for n in y["graph"]["nodes"]])
    assert len(y["graph"]["branches"]) == 3
    for b in y["graph"]["branches"][1:]:
        d = nodes[b["nodes"][-1]] - nodes[b["nodes"][0]]
        assert math.degrees(math.acos(d[0] / np.linalg.norm(d))) == pytest.approx(25.0, abs=0.5)
    with pytest.raises(ValueError, match="colour"):
        magvine.phantom("tube", colour=3)
    with pytest.raises(ValueError, match="segments"):
        magvine.phantom("tube", segments="many")
    with pytest.raises(ValueError, match="kind"):
        magvine.phantom("torus")


def test_airway_graph_is_the_command_lines_graph(tmp_path):
    stl = tmp_path / "y.stl"
    magvine.phantom("y_bifurcation", out=stl)
    subprocess.run([CLI, "mesh", "graph", str(stl), "--out", str(tmp_path / "graph.json")], check=True,
                   capture_output=True)
    with open(tmp_path / "graph.json") as f:
        assert magvine.airway_graph(str(stl)) == json.load(f)


def test_design_is_the_command_lines_design(tmp_path):
    scene = os.path.join(SRC, "assets", "scenes", "design_catheter.yaml")
    ours = magvine.design(scene, out=tmp_path / "py")
    subprocess.run([CLI, "design", scene, "--out", str(tmp_path / "cli")], check=True, capture_output=True)
    with open(tmp_path / "cli" / "design.json") as f:
        theirs = json.load(f)
    def untimed(x):  # the computing times (runtime_s, each iteration's time_s) differ between two runs
        if isinstance(x, dict):
            return {k: untimed(v) for k, v in x.items() if k not in ("runtime_s", "time_s")}
        return [untimed(v) for v in x] if isinstance(x, list) else x
    assert untimed(ours) == untimed(theirs)
    assert (tmp_path / "py" / "scene.yaml").read_text() == (tmp_path / "cli" / "scene.yaml").read_text()


def test_trials_are_the_command_lines_trials(tmp_path):
    scene = os.path.join(SRC, "assets", "scenes", "y_bifurcation_fluid_vine.yaml")
    ours = magvine.trials(scene, repeats=2, jobs=2, out=tmp_path / "py")
    subprocess.run([CLI, "trials", scene, "--repeats", "2", "--jobs", "2", "--out", str(tmp_path / "cli")],
                   check=True, capture_output=True)
    assert len(ours) == 2 and [t["repeat"] for t in ours] == [0, 1]
    # trials.csv without its runtime column: the same trials, the same outcomes.
    def rows(path):
        with open(path) as f:
            table = list(csv.DictReader(f))
        return [{k: v for k, v in r.items() if "runtime" not in k} for r in table]
    assert rows(tmp_path / "py" / "trials.csv") == rows(tmp_path / "cli" / "trials.csv")
    for t, row in zip(ours, rows(tmp_path / "cli" / "trials.csv")):
        assert str(t["seed"]) == row["seed"]
