"""magvine: magnetically steered soft robots in anatomy, from Python (docs/python.md).

The verbs of the command line as functions returning what it writes (run, trials, mesh_check, airway_graph,
phantom, design, field), Simulation (an experiment stepped from Python, with numpy copies of its state) and NavigationEnv (a
navigation task shaped like a Gymnasium environment). SI units throughout.
"""

from ._magvine import (  # noqa: F401
    Scene,
    Simulation,
    SimulationError,
    airway_graph,
    design,
    field,
    mesh_check,
    phantom,
    run,
    trials,
)
from .env import Box, DictSpace, NavigationEnv  # noqa: F401

__all__ = [
    "Box",
    "DictSpace",
    "NavigationEnv",
    "Scene",
    "Simulation",
    "SimulationError",
    "airway_graph",
    "design",
    "field",
    "mesh_check",
    "phantom",
    "run",
    "trials",
]
