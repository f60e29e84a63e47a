"""NavigationEnv: steering a vine to its target with the magnet, shaped like a Gymnasium environment.

Gymnasium is not a Debian package, so the environment and its spaces (Box, DictSpace) follow its interface without
depending on it: reset(seed, options) -> (obs, info), step(action) -> (obs, reward, terminated, truncated, info),
observation_space / action_space with sample() and seed(), render() and close(). docs/python.md documents the
action, the observation and the reward with their weights.
"""

import math

import numpy as np

from ._magvine import Scene, Simulation, SimulationError


class Box:
    """A box of R^n (Gymnasium's Box): bounds low and high (arrays of `shape`), dtype, sample(), contains(), seed()."""

    def __init__(self, low, high, shape=None, dtype=np.float64):
        self.dtype = np.dtype(dtype)
        if shape is None:
            shape = np.shape(low)
        self.shape = tuple(shape)
        self.low = np.broadcast_to(np.asarray(low, dtype=self.dtype), self.shape).copy()
        self.high = np.broadcast_to(np.asarray(high, dtype=self.dtype), self.shape).copy()
        self._rng = np.random.default_rng()

    def seed(self, seed=None):
        self._rng = np.random.default_rng(seed)
        return [seed]

    def sample(self):
        """A uniform sample (bounded dimensions), else a standard normal one."""
        if np.issubdtype(self.dtype, np.integer):
            return self._rng.integers(self.low, self.high, endpoint=True, dtype=self.dtype)
        bounded = np.isfinite(self.low) & np.isfinite(self.high)
        x = self._rng.standard_normal(self.shape)
        u = self._rng.uniform(np.where(bounded, self.low, 0.0), np.where(bounded, self.high, 1.0))
        return np.where(bounded, u, x).astype(self.dtype)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == self.shape and bool(np.all(x >= self.low) and np.all(x <= self.high))

    def __repr__(self):
        return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"


class DictSpace:
    """A dict of spaces (Gymnasium's Dict): sample() gives a dict, seed() seeds each space from one seed."""

    def __init__(self, spaces):
        self.spaces = dict(spaces)

    def seed(self, seed=None):
        seeds = np.random.SeedSequence(seed).spawn(len(self.spaces))
        for space, s in zip(self.spaces.values(), seeds):
            space.seed(int(s.generate_state(1)[0]))
        return [seed]

    def sample(self):
        return {k: s.sample() for k, s in self.spaces.items()}

    def contains(self, x):
        return set(x) == set(self.spaces) and all(s.contains(x[k]) for k, s in self.spaces.items())

    def __getitem__(self, key):
        return self.spaces[key]

    def __repr__(self):
        return "DictSpace(" + ", ".join(f"{k}: {s}" for k, s in self.spaces.items()) + ")"


def _turn(axis, rotation):
    """The unit axis turned by a rotation vector [rad] (Rodrigues)."""
    angle = float(np.linalg.norm(rotation))
    if angle < 1e-15:
        return axis
    k = rotation / angle
    turned = axis * math.cos(angle) + np.cross(k, axis) * math.sin(angle) + k * np.dot(k, axis) * (1 - math.cos(angle))
    return turned / np.linalg.norm(turned)


def _resample(nodes, count):
    """`count` points evenly spaced along the polyline of nodes (clamp to tip)."""
    seg = np.linalg.norm(np.diff(nodes, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, arc[-1], count)
    return np.stack([np.interp(s, arc, nodes[:, c]) for c in range(3)], axis=1)


class NavigationEnv:
    """Grow the scene's vine (or push its rod) to its target by moving a magnet, setting the pressure and releasing
    the tether.

    Action (8 numbers in [-1, 1]): the magnet's move (3, times max_move [m]), its axis's turn (a rotation vector, 3,
    times max_turn [rad]), the pressure (−1 … 1 over pressure_range [Pa]; by default half the scene's starting
    pressure to all of it) and the tether (the released length set to
    the everted length plus the value times tether_step [m]; negative values pull the body back). One action holds
    for frame_skip steps of the scene's dt.

    Observation (a dict): tip_position [m], tip_direction, body (body_points points along the body [m]),
    everted_length [m], wall_force ([largest normal force on a node, total normal force] [N]), magnet_position [m],
    magnet_axis, progress (0–1 along the path to the target) and, with camera=True, image (the tip camera,
    image_size² RGB).

    Reward: progress_weight × (the step's gain in progress) − force_weight × (the largest wall normal force on a node
    at its end, N) + success_bonus on reaching the target. Terminated: the target reached, a step without
    equilibrium or the vine burst (info["failure"] says which); truncated: max_steps actions or the scene's duration.

    Deterministic for a seed: reset(seed=s) draws the episode's trial perturbation (perturb=True: the one
    `magvine trials` applies with that seed; False: the scene as written) and seeds the spaces. Each env owns its
    simulation; several envs run in one process and in parallel threads.
    """

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, scene, *, magnet=0, max_steps=80, frame_skip=5, max_move=0.005, max_turn=math.radians(5.0),
                 pressure_range=None, tether_step=0.002, progress_weight=10.0, force_weight=0.1, success_bonus=1.0,
                 body_points=16, camera=False, image_size=64, perturb=True, render_mode=None, render_size=160):
        self.scene = scene if isinstance(scene, Scene) else Scene(scene)
        probe = Simulation(self.scene)
        if probe.steered:
            raise ValueError("NavigationEnv moves the magnets itself: the scene must not have control.navigator")
        if not (isinstance(magnet, int) and 0 <= magnet < probe.magnets):
            raise ValueError(f"magnet: the scene has {probe.magnets} magnet(s), not magnet {magnet!r}")
        if probe.path is None:
            raise ValueError("NavigationEnv needs a target and an airway graph (a generated phantom's or anatomy.graph)")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array' (got {render_mode!r})")
        p0 = probe.state.pressure
        self.pressure_range = tuple(pressure_range) if pressure_range is not None else (0.5 * p0, p0)
        if not (0.0 <= self.pressure_range[0] < self.pressure_range[1] and all(map(math.isfinite, self.pressure_range))):
            raise ValueError(f"pressure_range must be (low, high) with 0 <= low < high (got {self.pressure_range})")
        for name, value in (("max_steps", max_steps), ("frame_skip", frame_skip), ("body_points", body_points)):
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be an integer >= 1 (got {value!r})")
        self.magnet = magnet
        self.max_steps = max_steps
        self.frame_skip = frame_skip
        self.max_move = float(max_move)
        self.max_turn = float(max_turn)
        self.tether_step = float(tether_step)
        self.progress_weight = float(progress_weight)
        self.force_weight = float(force_weight)
        self.success_bonus = float(success_bonus)
        self.body_points = body_points
        self.camera = camera
        self.image_size = image_size
        self.perturb = perturb
        self.render_mode = render_mode
        self.render_size = render_size
        self.dt = probe.dt * frame_skip
        self.action_space = Box(-1.0, 1.0, (8,))
        inf = np.inf
        spaces = {
            "tip_position": Box(-inf, inf, (3,)),
            "tip_direction": Box(-1.0, 1.0, (3,)),
            "body": Box(-inf, inf, (body_points, 3)),
            "everted_length": Box(0.0, inf, (1,)),
            "wall_force": Box(0.0, inf, (2,)),
            "magnet_position": Box(-inf, inf, (3,)),
            "magnet_axis": Box(-1.0, 1.0, (3,)),
            "progress": Box(0.0, 1.0, (1,)),
        }
        if camera:
            spaces["image"] = Box(0, 255, (image_size, image_size, 3), np.uint8)
        self.observation_space = DictSpace(spaces)
        self.sim = None
        self._rng = np.random.default_rng()

    def reset(self, seed=None, options=None):
        """Starts an episode: (observation, info). seed: reseeds the episode generator and the spaces."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
            self.action_space.seed(seed)
            self.observation_space.seed(seed)
        trial = int(self._rng.integers(0, 2**31 - 1))
        self.sim = Simulation(self.scene, seed=trial if self.perturb else None)
        s = self.sim.state
        self._position = s.magnet_positions[self.magnet].copy()
        self._axis = s.magnet_axes[self.magnet].copy()
        self._progress = self.sim.progress
        self._steps = 0
        self._over = False
        return self._observation(s), self._info(s, trial=trial)

    def step(self, action):
        """Applies an action for frame_skip steps: (observation, reward, terminated, truncated, info)."""
        if self.sim is None or self._over:
            raise RuntimeError("NavigationEnv.step: call reset() first (the episode has ended)")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (8,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be 8 finite numbers in [-1, 1] (got shape {a.shape})")
        a = np.clip(a, -1.0, 1.0)
        self._position = self._position + self.max_move * a[0:3]
        self._axis = _turn(self._axis, self.max_turn * a[3:6])
        low, high = self.pressure_range
        pressure = low + 0.5 * (a[6] + 1.0) * (high - low)
        tether = max(0.0, self.sim.state.everted_length + self.tether_step * a[7])
        failure = None
        try:
            self.sim.step(pressure=pressure, tether=tether, magnet_pose={self.magnet: (self._position, self._axis)})
            for _ in range(self.frame_skip - 1):
                if self.sim.done:
                    break
                self.sim.step()
        except SimulationError as e:
            failure = str(e)
        if failure is None and self.sim.state.burst:
            failure = "the vine burst (its pressure above what its film holds)"
        s = self.sim.state
        self._steps += 1
        progress = self.sim.progress
        reward = self.progress_weight * (progress - self._progress) - self.force_weight * s.max_wall_normal
        self._progress = progress
        if s.success:
            reward += self.success_bonus
        terminated = bool(s.success) or failure is not None
        truncated = not terminated and (self._steps >= self.max_steps or self.sim.done or self.sim.ended)
        self._over = terminated or truncated
        info = self._info(s)
        if failure is not None:
            info["failure"] = failure
        return self._observation(s), float(reward), terminated, truncated, info

    def render(self):
        """The tip camera's picture (render_size², RGB uint8) with render_mode 'rgb_array'; None otherwise."""
        if self.render_mode != "rgb_array" or self.sim is None:
            return None
        return self.sim.render(width=self.render_size, height=self.render_size)

    def close(self):
        self.sim = None

    def _observation(self, s):
        obs = {
            "tip_position": s.tip_position,
            "tip_direction": s.tip_frame[:, 0].copy(),
            "body": _resample(s.nodes, self.body_points),
            "everted_length": np.array([s.everted_length]),
            "wall_force": np.array([s.max_wall_normal, float(np.linalg.norm(s.wall_normal, axis=1).sum())]),
            "magnet_position": self._position.copy(),
            "magnet_axis": self._axis.copy(),
            "progress": np.array([self._progress]),
        }
        if self.camera:
            obs["image"] = self.sim.render(width=self.image_size, height=self.image_size)
        return obs

    def _info(self, s, **extra):
        info = {"time": s.time, "progress": self._progress, "success": bool(s.success),
                "max_wall_normal_N": s.max_wall_normal, "everted_length_m": s.everted_length}
        info.update(extra)
        return info
