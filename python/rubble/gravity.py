"""The gravitational field of N point masses (gravity/, standalone): direct sum or Barnes-Hut tree.

    a = rubble.gravity.field(positions, masses, method="tree", theta=0.5, order=2)
    a, phi = rubble.gravity.field(positions, masses, potential=True)

a_i = -G sum_j m_j (x_i - x_j) / (|x_i - x_j|^2 + eps^2)^(3/2), phi_i likewise (gravity/README.md).
Inputs are converted to contiguous float64 (a copy only when they are not already). The GIL is
released during the evaluation; results do not depend on the number of OpenMP threads.
"""
import numpy as np

from ._rubble import _gravity_field

#: The gravitational constant rubble uses by default, m^3 kg^-1 s^-2.
G = 6.674e-11


def field(positions, masses, method="tree", theta=0.5, order=2, G=G, softening=0.0, potential=False,
          leaf_size=16, group_size=64, precision="double", timings=False, backend="cpu"):
    """Accelerations (N, 3) m/s^2 of every particle due to all others.

    positions: (N, 3) m; masses: (N,) kg; method: "direct" (exact O(N^2)) or "tree" (Barnes-Hut,
    opening angle theta > 0, multipole order 1 or 2); G in m^3 kg^-1 s^-2; softening: Plummer
    length eps, m (0: none). precision: "double", or "single" for the tree's kernels in float
    (faster; each term within ~1e-6 of double, far below the tree's own error). backend: "cpu",
    or "cuda" for an NVIDIA GPU (direct sum, or the tree built and walked there, double precision;
    ValueError with the reason where it cannot run). potential=True also returns phi (N,) J/kg;
    timings=True appends {"build_seconds", "walk_seconds", "transfer_seconds"}. Raises ValueError
    for bad input.
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    masses = np.ascontiguousarray(masses, dtype=np.float64)
    acceleration, phi, build, walk, transfer = _gravity_field(positions, masses, method, float(theta), int(order),
                                                              float(G), float(softening), bool(potential),
                                                              int(leaf_size), int(group_size), str(precision),
                                                              str(backend))
    out = (acceleration, phi) if potential else (acceleration,)
    if timings:
        out = out + ({"build_seconds": build, "walk_seconds": walk, "transfer_seconds": transfer},)
    return out[0] if len(out) == 1 else out
