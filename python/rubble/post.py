"""Post-processing: the metrics of `rubble post` on a run file or a live simulation, and `rubble post` itself.

    m = rubble.post.metrics("run/run.h5")          # {name: array over snapshots}
    m = rubble.post.metrics(sim)                   # {name: value} now
    files = rubble.post.process("run/run.h5", "post", vtk=True)   # = rubble post RUN.h5 --vtk

Metric names and definitions: docs/postprocessing.md (coordination, coordination_without_rattlers,
packing_fraction, aggregate_diameter, kinetic_energy, potential_energy, ...).
"""
import os
import sys

from ._rubble import RunReader, Simulation, VtkSeries, _post_process_run  # noqa: F401


def metrics(source, every=1, impulse_threshold=0.0):
    """Metrics of a Simulation (a dict of floats, now) or of a run file path / RunReader (a dict of
    arrays, one entry per snapshot, every `every`-th and always the last)."""
    if isinstance(source, Simulation):
        return source.metrics(impulse_threshold=impulse_threshold)
    reader = source if isinstance(source, RunReader) else RunReader(os.fspath(source))
    return reader.metrics(every=every, impulse_threshold=impulse_threshold)


def process(run_file, output="rubble-post", vtk=False, plots=True, every=1, bins=20, python=None):
    """What `rubble post RUN.h5 --out OUTPUT [--vtk] [--every N] [--no-plots]` writes; returns the files.

    The plots are drawn with `python` (default: this interpreter) and the package's own plots.py;
    without matplotlib they are left out with a warning on stderr, the other files written."""
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plots.py")
    return _post_process_run(os.fspath(run_file), os.fspath(output), bool(vtk), bool(plots), int(every), int(bins),
                             python or sys.executable, script)


def read_run(run_file):
    """Opens a run file for reading (a RunReader: series(), snapshot(i), metrics(), scene_text)."""
    return RunReader(os.fspath(run_file))
