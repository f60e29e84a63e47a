"""A scripted and a random policy on the Y phantom with magvine.NavigationEnv (docs/python.md).

The scripted policy does what the bench scene's keyframes do, through the environment's actions: it brings the EPM
beside daughter 0-0 (70, 110, 0) mm with its axis along −y while the tether holds the vine, then releases the tether
at full pressure, so the magnetic fluid turns the tip into that daughter. The random policy samples the action space.

    PYTHONPATH=$(make -s python-path) /usr/bin/python3 examples/python/policies.py --episodes 3
"""
import argparse

import numpy as np

import magvine

GOAL = np.array([0.070, 0.110, 0.0])  # where the scene's keyframes put the EPM [m]


def scripted(env, obs):
    """Magnet to GOAL first (tether held), then the tether released at full pressure."""
    action = np.zeros(8)
    to_goal = GOAL - obs["magnet_position"]
    distance = np.linalg.norm(to_goal)
    action[0:3] = to_goal / max(distance, env.max_move)  # at most max_move per action
    action[6] = 1.0  # the top of pressure_range
    action[7] = 1.0 if distance < 0.01 else 0.0  # hold the tether until the magnet is there
    return action


def episode(env, policy, seed):
    obs, info = env.reset(seed=seed)
    total = 0.0
    while True:
        action = policy(env, obs) if policy else env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        if terminated or truncated:
            return total, info


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="assets/scenes/y_bifurcation_fluid_vine.yaml")
    parser.add_argument("--episodes", type=int, default=4)
    args = parser.parse_args()
    env = magvine.NavigationEnv(args.scene, max_steps=120)
    print("policy    seed  return  success  progress  time [s]")
    for name, policy in (("scripted", scripted), ("random", None)):
        for seed in range(args.episodes):
            total, info = episode(env, policy, seed)
            print(f"{name:8s}  {seed:4d}  {total:6.2f}  {str(info['success']):7s}  {info['progress']:8.2f}  "
                  f"{info['time']:8.2f}")


if __name__ == "__main__":
    main()
