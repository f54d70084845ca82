"""rubble: Contact Dynamics (Moreau-Jean + NLGS, LMGC90 style) for gravitational aggregates.

The Python side of rubble, built from the same C++ libraries as the `rubble` command line:

    import rubble
    scene = rubble.pack("cubic-grid", n=125, dmin=7.5, dmax=10, seed=1)   # = rubble pack
    sim = rubble.Simulation(scene)
    sim.run(until="rest", callback=lambda s: print(s.time), every=1000)
    print(sim.metrics()["coordination"], sim.positions.shape)          # (N, 3) view, no copy

SI units throughout. Orientations are unit quaternions body -> world in the order (x, y, z, w)
(scipy's, Eigen's memory order); the run file stores (w, x, y, z); see rubble.quaternion.
Reference: docs/python.md.
"""
from ._rubble import (  # noqa: F401  (re-exported)
    CheckpointError,
    FclibFileError,
    NumericalFailure,
    RunReader,
    Scene,
    SceneError,
    Simulation,
    VtkSeries,
    default_scene,
    load_scene,
    parse_scene,
    random_polyhedron,
)
from . import fclib, gravity, post, quaternion  # noqa: F401
from .scenes import pack, scene_from_dict, toml_text  # noqa: F401

from ._rubble import _stage_names

#: Names of the stages of a step, in execution order (keys of Simulation.stage_seconds).
STAGES = tuple(_stage_names())

#: Contact status codes of Simulation.contacts()["status"].
CONTACT_STATUS = {0: "open", 1: "sticking", 2: "sliding"}

__all__ = [
    "CheckpointError", "FclibFileError", "NumericalFailure", "RunReader", "Scene", "SceneError", "Simulation",
    "VtkSeries", "default_scene", "load_scene", "parse_scene", "random_polyhedron", "fclib", "gravity", "post",
    "quaternion", "pack", "scene_from_dict", "toml_text", "STAGES", "CONTACT_STATUS",
]
