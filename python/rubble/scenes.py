"""Scenes from Python: `rubble pack` with the command's options, and scenes built as dicts.

    scene = rubble.pack("cubic-grid", n=3375, shape="polyhedra", dmin=7.5, dmax=10, seed=1)
    scene = rubble.scene_from_dict({
        "name": "drop", "time": {"dt": 1e-4, "end_time": 0.5},
        "gravity": {"type": "uniform", "acceleration": [0, 0, -9.81]},
        "materials": [{"name": "glass", "density": 2500.0}],
        "default_contact_law": {"friction": 0.3},
        "walls": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}],
        "bodies": [{"shape": "sphere", "radius": 0.01, "position": [0, 0, 0.05]}],
    })

A dict is written as scene-file TOML (docs/scene-file.md: the keys are the file's keys; a list of
dicts is an array of tables such as [[bodies]]) and parsed by the same parser as `rubble run`, so
every key is checked and a mistake raises SceneError naming the key and the line of the text
(scene.text shows it).
"""
import math
import numbers

import numpy as np

from ._rubble import _pack, _PackOptions, parse_scene


def pack(kind="cubic-grid", n=1000, shape="spheres", polyhedron_fraction=0.5, dmin=7.5, dmax=10.0,
         distribution="volume-fraction", bins=None, bin_fractions="volume", density=5164.0, friction=0.0,
         restitution=0.0, seed=1, volume_fraction=0.1, cloud_radius=0.0, box_width=0.0, g=9.80665, end_time=0.0,
         name="", explicit=False):
    """The scene `rubble pack KIND --n N ...` writes (same options, same defaults, same text).

    kind: "cubic-grid" (n = k^3 grains on a grid of mesh dmax: the accretion study), "cloud" (a
    random loose cloud in a ball) or "box" (a deposit in an open box under uniform gravity g).
    bins: "d:f,d:f" or a list of (diameter, fraction) pairs (distribution="bins"). explicit=True
    lists every grain in scene.text instead of the generator and seed. Returns a Scene; ValueError
    for bad options, SceneError if the scene does not parse.
    """
    o = _PackOptions()
    o.kind, o.count, o.shape, o.polyhedron_fraction = kind, int(n), shape, float(polyhedron_fraction)
    o.d_min, o.d_max, o.distribution = float(dmin), float(dmax), distribution
    if bins is not None and not isinstance(bins, str):
        bins = ",".join(f"{float(d)!r}:{float(f)!r}" for d, f in bins)
    o.bins = bins or ""
    o.bin_fractions, o.density, o.friction, o.restitution = bin_fractions, float(density), float(friction), float(restitution)
    o.seed, o.volume_fraction, o.cloud_radius, o.box_width = int(seed), float(volume_fraction), float(cloud_radius), float(box_width)
    o.g, o.end_time, o.name, o.explicit_grains = float(g), float(end_time), name, bool(explicit)
    return _pack(o)


def _value(v, key):
    """One TOML value."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        x = float(v)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)  # shortest text that reads back to the same double
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, key) for x in v) + "]"
    raise TypeError(f"{key}: cannot write a {type(v).__name__} in a scene file")


def _is_table_list(v):
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def toml_text(scene):
    """The scene-file text of a dict (see the module comment)."""
    lines = []

    def table(d, prefix):
        simple = [(k, v) for k, v in d.items() if not isinstance(v, dict) and not _is_table_list(v)]
        for k, v in simple:
            lines.append(f"{k} = {_value(v, prefix + k)}")
        for k, v in d.items():
            if isinstance(v, dict):
                lines.append("")
                lines.append(f"[{prefix}{k}]")
                table(v, f"{prefix}{k}.")
            elif _is_table_list(v):
                for item in v:
                    lines.append("")
                    lines.append(f"[[{prefix}{k}]]")
                    table(item, f"{prefix}{k}.")

    table(scene, "")
    while lines and not lines[0]:
        lines.pop(0)
    return "\n".join(lines) + "\n"


def scene_from_dict(scene, source="<dict>"):
    """A Scene from a dict of scene-file keys (see the module comment). Raises SceneError."""
    return parse_scene(toml_text(scene), source)
