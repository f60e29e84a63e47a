"""magvine.NavigationEnv (docs/python.md) on the Y phantom: deterministic per seed, one env per thread gives its own
single-threaded result, 1000 random steps without an exception, the reward as documented, the spaces' samples inside
them. Run by ctest with PYTHONPATH at the built module."""
import os
import threading

import numpy as np
import pytest

from support import SRC, Y, magvine  # the module, or a skip



@pytest.fixture(scope="module")
def scene():
    return magvine.Scene(Y)  # loaded once, shared by the envs


def episode(env, seed, steps):
    """Observations and rewards of `steps` random actions after reset(seed)."""
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rewards = []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        out.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    return out, rewards


def same(a, b):
    for (oa, ob) in zip(a[0], b[0]):
        assert oa.keys() == ob.keys()
        for k in oa:
            np.testing.assert_array_equal(oa[k], ob[k], err_msg=k)
    assert a[1] == b[1]


def test_the_same_seed_gives_the_same_observations(scene):
    env = magvine.NavigationEnv(scene, frame_skip=2)
    first = episode(env, 7, 15)
    second = episode(env, 7, 15)
    same(first, second)
    other = episode(env, 8, 15)
    assert not np.array_equal(first[0][-1]["tip_position"], other[0][-1]["tip_position"])


def test_two_envs_in_two_threads_give_their_own_results(scene):
    envs = [magvine.NavigationEnv(scene, frame_skip=2) for _ in range(2)]
    alone = [episode(envs[i], 10 + i, 12) for i in range(2)]
    together = [None, None]
    threads = [threading.Thread(target=lambda i=i: together.__setitem__(i, episode(envs[i], 10 + i, 12)))
               for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, together):
        same(a, b)


def test_a_thousand_random_steps(scene):
    env = magvine.NavigationEnv(scene, frame_skip=1, max_steps=150)
    env.reset(seed=3)
    episodes = 1
    for _ in range(1000):
        action = env.action_space.sample()
        assert env.action_space.contains(action)
        obs, reward, terminated, truncated, info = env.step(action)
        assert np.isfinite(reward)
        for k, space in env.observation_space.spaces.items():
            assert obs[k].shape == space.shape, k
            assert np.all(np.isfinite(obs[k])), k
        if terminated or truncated:
            env.reset()
            episodes += 1
    assert episodes >= 6  # 150 actions at most per episode


def test_the_reward_is_progress_gained_less_the_wall_force(scene):
    # Against the simulation's own figures (its progress along the path and its largest wall force), read past the
    # env: 10 per path gained, 0.1 per newton, 1 on success.
    env = magvine.NavigationEnv(scene, frame_skip=3, progress_weight=10.0, force_weight=0.1, success_bonus=1.0)
    env.reset(seed=5)
    progress = env.sim.progress
    forces = []
    for _ in range(60):
        obs, reward, terminated, truncated, info = env.step(np.array([0, -1, 0, 0, 0, 0, 1, 1.0]))
        expected = 10.0 * (env.sim.progress - progress) - 0.1 * env.sim.state.max_wall_normal
        expected += 1.0 if env.sim.state.success else 0.0
        assert reward == pytest.approx(expected, rel=1e-12, abs=1e-15)
        assert obs["progress"][0] == env.sim.progress
        progress = env.sim.progress
        forces.append(env.sim.state.max_wall_normal)
        if terminated or truncated:
            break
    assert max(forces) > 0.0  # the vine met the wall: the force term was exercised


def test_the_env_moves_the_magnet_it_is_given(tmp_path, scene):
    with pytest.raises(ValueError, match="magnet"):
        magvine.NavigationEnv(scene, magnet=1)  # the Y scene has one
    with pytest.raises(ValueError, match="magnet"):
        magvine.NavigationEnv(scene, magnet=-1)
    env = magvine.NavigationEnv(scene, perturb=False)
    obs, _ = env.reset(seed=1)
    start = obs["magnet_position"].copy()
    obs, *_ = env.step(np.array([1.0, 0, 0, 0, 0, 0, 0, 0]))
    np.testing.assert_allclose(env.sim.state.magnet_positions[0], start + [0.005, 0, 0], atol=1e-15)
    np.testing.assert_allclose(obs["magnet_position"], env.sim.state.magnet_positions[0], atol=0)


def test_a_scene_with_a_navigator_is_refused():
    with pytest.raises(ValueError, match="navigator"):
        magvine.NavigationEnv(os.path.join(SRC, "assets", "scenes", "bronchial_tree_navigator.yaml"))


def test_in_a_platform_scene_the_arm_carries_the_magnet_where_the_actions_move_it():
    # The demo scene (an iiwa arm holds the EPM) without its navigator, aimed at the end of branch 0-0-1: the env's
    # magnet moves are asked of the arm (end-effector requests); the arm tracks them (it lags: within 5 mm after a
    # step of rest).
    yaml = pytest.importorskip("yaml", reason="python3-yaml is not installed")
    with open(os.path.join(SRC, "assets", "scenes", "bronchial_tree_platform.yaml")) as f:
        scene = yaml.safe_load(f)
    del scene["control"]["navigator"]
    del scene["outputs"]
    graph = magvine.phantom("bronchial_tree", max_generation=3)["graph"]
    branch = next(b for b in graph["branches"] if b["name"] == "0-0-1")
    end = graph["nodes"][branch["nodes"][-2]]["position"]  # mm, inside the branch's end
    scene["target"] = {"position": end, "tolerance": 6}
    env = magvine.NavigationEnv(scene, frame_skip=2, perturb=False)
    obs, _ = env.reset(seed=0)
    start = env.sim.state.magnet_positions[0].copy()
    for _ in range(6):
        obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 1.0, 0, 0, 0, 1, 1]))
        assert not terminated, info
    for _ in range(3):
        obs, *_ = env.step(np.array([0, 0, 0, 0, 0, 0, 1, 1.0]))
    moved = env.sim.state.magnet_positions[0] - start
    assert moved[2] == pytest.approx(6 * 0.005, abs=0.005)  # asked 30 mm along +z
    assert abs(moved[0]) < 0.005 and abs(moved[1]) < 0.005
