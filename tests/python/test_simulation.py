"""magvine.Simulation (docs/python.md): stepping from Python gives `magvine run`'s trajectory and metrics; the state's
arrays against independent evaluations; a driver's pressure and magnet poses act as the physics says; bad input raises
ValueError naming it. Run by ctest with PYTHONPATH at the built module and MAGVINE at the CLI."""
import json
import math
import threading

import numpy as np
import pytest

from support import TIMING, Y, cli_run, magvine, scene  # the module, or a skip



@pytest.mark.parametrize("name", ["y_bifurcation_fluid_vine.yaml", "bronchial_tree_navigator.yaml"])
def test_stepping_gives_the_command_lines_trajectory_and_metrics(name, tmp_path):
    sim = magvine.Simulation(scene(name))
    samples = []
    while not sim.done:
        sim.step()
        s = sim.state
        samples.append((s.time, s.tip_position, s.everted_length))
    ours = sim.finish(out=tmp_path / "py")
    theirs, rows = cli_run(scene(name), tmp_path / "cli")
    assert set(ours) == set(theirs)
    for key in set(ours) - TIMING:
        assert ours[key] == theirs[key], key  # the same run: to the last bit
    # Every step's tip against tip_trajectory.csv, which holds 10 significant digits (hence rtol 1e-9).
    assert len(samples) == len(rows)
    for (t, tip, length), row in zip(samples, rows):
        assert t == pytest.approx(float(row["t_s"]), rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(tip, [float(row[c]) for c in ("x_m", "y_m", "z_m")], rtol=1e-9, atol=1e-12)
        assert length == pytest.approx(float(row["length_m"]), rel=1e-9)


def test_the_state_is_the_body_and_its_field(tmp_path):
    sim = magvine.Simulation(Y)
    while sim.time < 1.5:
        sim.step()
    s = sim.state
    n = len(s.nodes)
    assert s.nodes.shape == (n, 3) and s.tangents.shape == (n, 3) and s.field.shape == (n, 3)
    assert s.wall_normal.shape == (n, 3) and s.contact_pressure.shape == (n,)
    np.testing.assert_allclose(s.tip_position, s.nodes[-1])
    np.testing.assert_allclose(np.linalg.norm(s.tangents, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(s.tip_frame.T @ s.tip_frame, np.eye(3), atol=1e-9)
    # The everted length is the arc length of the body beyond its first node (within the body's stretch, < 1 %).
    arc = np.linalg.norm(np.diff(s.nodes, axis=0), axis=1).sum()
    assert arc == pytest.approx(s.everted_length, rel=0.01)
    # Past the last keyframe (t = 1 s) the EPM rests at (70, 110, 0) mm, axis −y: the field at the nodes is that
    # magnet's, evaluated independently by magvine.field from a magnets file.
    magnets = tmp_path / "epm.yaml"
    magnets.write_text("units: {length: mm}\nmagnets:\n  - {kind: cylinder, diameter: 101.6, length: 101.6, "
                       "polarisation: 1.48, position: [70, 110, 0], axis: [0, -1, 0]}\n")
    np.testing.assert_allclose(s.magnet_positions[0], [0.070, 0.110, 0.0], atol=1e-12)
    b, _ = magvine.field(str(magnets), s.nodes)
    np.testing.assert_allclose(s.field, b, rtol=1e-12, atol=1e-15)


def test_below_the_yield_pressure_the_vine_does_not_grow():
    # The growth law: the tip advances only while P exceeds the yield pressure Y (20 kPa in this scene).
    sim = magvine.Simulation(Y)
    for _ in range(5):
        sim.step()
    grown = sim.state.everted_length
    sim.step(pressure=15e3)
    for _ in range(24):
        sim.step()
    assert sim.state.pressure == 15e3
    assert sim.state.everted_length == pytest.approx(grown, abs=1e-4)  # held within 0.1 mm over 0.5 s
    sim.step(pressure=35e3)  # back above yield: it grows again
    for _ in range(24):
        sim.step()
    assert sim.state.everted_length > grown + 5e-3


def test_a_driven_magnet_goes_where_it_is_put():
    sim = magvine.Simulation(Y)
    sim.step(magnet_pose=([0.08, 0.12, 0.01], [0.0, -2.0, 0.0]))
    sim.step()  # the pose holds
    np.testing.assert_allclose(sim.state.magnet_positions[0], [0.08, 0.12, 0.01])
    np.testing.assert_allclose(sim.state.magnet_axes[0], [0.0, -1.0, 0.0], atol=1e-12)


def test_a_custom_step_advances_time_by_it():
    sim = magvine.Simulation(Y)
    sim.step(dt=0.005)
    sim.step(dt=0.005)
    assert sim.time == pytest.approx(0.01, abs=1e-12)
    sim.step()  # back on the scene's grid: the next multiple of dt
    assert sim.time == pytest.approx(0.02, abs=1e-12)


@pytest.mark.parametrize("kwargs, key", [
    ({"dt": -0.01}, "dt"),
    ({"dt": math.nan}, "dt"),
    ({"pressure": math.inf}, "pressure"),
    ({"magnet_pose": ([0.0, math.nan, 0.0], [0.0, 0.0, 1.0])}, "magnet_pose"),
    ({"magnet_pose": {3: ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])}}, "magnet_pose"),
    ({"magnet_pose": ([0.0, 0.0], [0.0, 0.0, 1.0])}, "magnet_pose"),
])
def test_a_bad_step_raises_value_error_naming_it(kwargs, key):
    sim = magvine.Simulation(Y)
    with pytest.raises(ValueError, match=key):
        sim.step(**kwargs)


def test_a_nan_or_unknown_key_in_a_dict_scene_raises_value_error_naming_it():
    yaml = pytest.importorskip("yaml", reason="python3-yaml is not installed")
    with open(Y) as f:
        good = yaml.safe_load(f)
    bad = json.loads(json.dumps(good))
    bad["robot"]["diameter"] = math.nan
    with pytest.raises(ValueError, match="diameter"):
        magvine.Simulation(bad)
    bad = json.loads(json.dumps(good))
    bad["robot"]["colour"] = "red"
    with pytest.raises(ValueError, match="colour"):
        magvine.Simulation(bad)


def test_field_refuses_points_of_the_wrong_shape(tmp_path):
    magnets = tmp_path / "dipole.yaml"
    magnets.write_text("magnets:\n  - {kind: dipole, position: [0, 0, 0], moment: [0, 0, 1]}\n")
    with pytest.raises(ValueError, match="points"):
        magvine.field(str(magnets), np.zeros((4, 2)))


def test_two_simulations_in_two_threads_give_their_results_alone():
    def run(seed):
        sim = magvine.Simulation(Y, seed=seed)
        for _ in range(40):
            sim.step()
        return sim.state.nodes

    alone = [run(1), run(2)]
    together = [None, None]
    threads = [threading.Thread(target=lambda i=i: together.__setitem__(i, run(i + 1))) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, together):
        np.testing.assert_array_equal(a, b)


def test_the_tip_camera_looks_down_the_lumen():
    sim = magvine.Simulation(Y)
    for _ in range(10):
        sim.step()
    try:
        image = sim.render(width=96, height=96)
    except ValueError as e:  # a build without the render module, and only that
        if "render module" not in str(e):
            raise
        pytest.skip(str(e))
    assert image.shape == (96, 96, 3) and image.dtype == np.uint8
    # Straight down the parent tube: the lumen ahead is far and dark, the wall round it near and lit (the light is at
    # the lens and falls off with distance).
    grey = image.mean(axis=2)
    y, x = np.mgrid[0:96, 0:96]
    r = np.hypot(x - 47.5, y - 47.5)
    assert grey[r < 10].mean() < 0.5 * grey[(r > 30) & (r < 45)].mean()


def test_a_driver_with_its_own_dt_runs_to_the_duration():
    sim = magvine.Simulation(Y)
    while not sim.done:
        sim.step(dt=sim.dt / 2)
        if sim.state.success:
            break
    assert sim.state.success or sim.time >= sim.duration - 1e-9
    # done counts time, not steps: twice as many steps as `magvine run` takes for the same time
    assert sim.steps == pytest.approx(2 * sim.time / sim.dt, abs=1)


def test_a_burst_vine_keeps_the_time():
    # Above the film's burst pressure (hoop stress P·R/t over its strength: 2.9 MPa · 38 µm / 2.5 mm = 44 kPa for this
    # vine) the vine bursts: an outcome, not an error; its clock runs on with the steps.
    sim = magvine.Simulation(Y)
    sim.step()
    sim.step(pressure=60e3)
    assert sim.state.burst
    length = sim.state.everted_length
    for _ in range(5):
        sim.step()
    assert sim.time == pytest.approx(7 * sim.dt, abs=1e-12)
    assert sim.state.everted_length == length


def test_one_simulation_is_for_one_thread_at_a_time():
    # A second thread reading a simulation while another steps it gets RuntimeError or a whole state, never a torn one.
    sim = magvine.Simulation(Y)
    stop = threading.Event()
    seen = {"busy": 0, "whole": 0}

    def read():
        while not stop.is_set():
            try:
                s = sim.state
            except RuntimeError:
                seen["busy"] += 1
                continue
            assert len(s.nodes) == len(s.tangents) == len(s.field) == len(s.wall_normal)
            seen["whole"] += 1

    reader = threading.Thread(target=read)
    reader.start()
    try:
        for _ in range(100):
            while True:
                try:
                    sim.step()
                    break
                except RuntimeError as e:  # the reader holds it for a moment
                    assert "another thread" in str(e)
    finally:
        stop.set()
        reader.join()
    assert seen["whole"] > 0
