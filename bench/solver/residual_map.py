#!/usr/bin/python3
"""Where the residual of a frictional contact problem sits, point by point.

    PYTHONPATH=BUILD/python /usr/bin/python3 bench/solver/residual_map.py PROBLEM.hdf5 SWEEPS [SWEEPS ...]

PROBLEM is an FCLib local problem (e.g. a step of a run written by `bench_matched_accuracy CKPT
--write-fclib PROBLEM.hdf5`). For each SWEEPS it solves the problem from r = 0 by that many plain
sweeps (`rubble.fclib.solve(..., polish="none")`, as `rubble fclib PROBLEM --polish none
--max-iterations SWEEPS`) and prints the residual's norm, the share of its square held by the 1,
10, 100 and 1 000 worst points, how many of the 100 worst are loaded and sticking, and, from the
second SWEEPS on, how many of them are among the first solve's 100 worst. A point's residual is
the solve's `point_residual`: its Coulomb natural map in velocity units (nlgs_solver/
local_problem.hpp, `point_residuals`). Used in docs/accretion-study.md ("Still open") to show that
the frictional runs' residual at the sweep cap is spread over the pile, not held by a few points.
"""
import sys

import numpy as np

import rubble


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    path = sys.argv[1]
    mu = rubble.fclib.read(path)[2]
    first_worst = None
    for sweeps in (int(a) for a in sys.argv[2:]):
        # A tolerance no solve meets: exactly `sweeps` sweeps.
        solution = rubble.fclib.solve(path, tolerance=1e-300, max_iterations=sweeps, polish="none")
        residual = np.asarray(solution["point_residual"])
        R = np.asarray(solution["r"]).reshape(-1, 3)
        loaded = R[:, 0] > 0.0
        sticking = loaded & (np.linalg.norm(R[:, 1:], axis=1) < mu * R[:, 0] * (1.0 - 1e-9))
        order = np.argsort(-residual)
        squares = residual[order] ** 2
        share = np.cumsum(squares) / squares.sum()
        worst = order[:100]
        shares = "/".join(f"{share[min(k, len(share)) - 1]:.3f}" for k in (1, 10, 100, 1000))
        line = (f"{sweeps} sweeps: {len(mu)} points, {int(loaded.sum())} loaded; residual "
                f"{np.sqrt(squares.sum()):.3e}; share of the worst 1/10/100/1000: {shares}; of the 100 worst, "
                f"{int(sticking[worst].sum())} sticking, {int(loaded[worst].sum())} loaded")
        if first_worst is None:
            first_worst = set(worst.tolist())
        else:
            line += f"; {len(first_worst & set(worst.tolist()))} of them among the first solve's 100 worst"
        print(line)


if __name__ == "__main__":
    main()
