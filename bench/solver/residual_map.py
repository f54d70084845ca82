#!/usr/bin/python3
"""Where the residual of a frictional contact problem sits, point by point.

    /usr/bin/python3 bench/solver/residual_map.py PROBLEM.hdf5 SOLUTION.h5 [SOLUTION.h5 ...]

PROBLEM is an FCLib local problem (W, q, mu; e.g. a step of a run written by
`bench_matched_accuracy CKPT --write-fclib PROBLEM.hdf5`), each SOLUTION the file `rubble fclib
PROBLEM --out SOLUTION` writes (datasets r and u). For each solution it prints the residual's
norm and the share of its square carried by the 1, 10, 100 and 1 000 worst points, how many of
them are loaded and sticking, and, from the second solution on, how many of the 100 worst points
are those of the first.

The residual of a point is the Coulomb natural map in velocity units,
    F = W_nn (r - P_K(r - u~ / W_nn)),   u~ = u + mu ||u_T|| e_n,
with P_K the projection onto the friction cone ||r_T|| <= mu r_n and u~ De Saxce's modified
velocity (De Saxce and Feng 1991), which makes F vanish exactly on the law's three regimes
(open, sticking, sliding); without it a sliding point has a residual of mu ||u_T|| W_nn^-1.
Used in docs/accretion-study.md ("Still open") to show that the frictional runs' residual at the
sweep cap is spread over the pile, not held by a few points.
"""
import sys

import h5py
import numpy as np
import scipy.sparse as sp


def read_problem(path):
    """W (sparse, 3n x 3n), q and mu of an FCLib local problem (W stored as CSR, CSC or triplets)."""
    with h5py.File(path, "r") as f:
        g = f["fclib_local"]
        w = g["W"]
        m, n, nz = int(w["m"][0]), int(w["n"][0]), int(w["nz"][0])
        x, i, p = w["x"][()], w["i"][()], w["p"][()]
        if nz == -2:
            W = sp.csr_matrix((x, i, p), shape=(m, n))
        elif nz == -1:
            W = sp.csc_matrix((x, i, p), shape=(m, n))
        else:
            W = sp.coo_matrix((x[:nz], (i[:nz], p[:nz])), shape=(m, n)).tocsr()
        return W, g["vectors"]["q"][()], g["vectors"]["mu"][()]


def point_residuals(W, q, mu, r):
    """Per point: |F| (velocity units), and whether the point is loaded and sticking."""
    R = r.reshape(-1, 3)
    U = (W @ r + q).reshape(-1, 3)
    w_nn = W.diagonal().reshape(-1, 3)[:, 0]
    tangential = np.linalg.norm(U[:, 1:], axis=1)
    modified = U.copy()
    modified[:, 0] += mu * tangential
    x = R - modified / w_nn[:, None]
    xn, xt = x[:, 0], np.linalg.norm(x[:, 1:], axis=1)
    projected = np.zeros_like(x)
    inside = xt <= mu * xn
    polar = mu * xt <= -xn  # projects to the apex, 0
    projected[inside] = x[inside]
    side = ~inside & ~polar
    normal = (xn[side] + mu[side] * xt[side]) / (1.0 + mu[side] ** 2)
    projected[side, 0] = normal
    projected[side, 1:] = (mu[side] * normal / xt[side])[:, None] * x[side, 1:]
    residual = np.linalg.norm((R - projected) * w_nn[:, None], axis=1)
    loaded = R[:, 0] > 0.0
    sticking = loaded & (np.linalg.norm(R[:, 1:], axis=1) < mu * R[:, 0] * (1.0 - 1e-9))
    return residual, loaded, sticking


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    W, q, mu = read_problem(sys.argv[1])
    first_worst = None
    for path in sys.argv[2:]:
        with h5py.File(path, "r") as f:
            r = f["r"][()]
        residual, loaded, sticking = point_residuals(W, q, mu, r)
        order = np.argsort(-residual)
        squares = residual[order] ** 2
        share = np.cumsum(squares) / squares.sum()
        worst = order[:100]
        line = (f"{path}: {len(mu)} points, {int(loaded.sum())} loaded; residual {np.sqrt(squares.sum()):.3e}; "
                f"share of the worst 1/10/100/1000: " + "/".join(f"{share[min(k, len(share)) - 1]:.3f}"
                                                                 for k in (1, 10, 100, 1000)) +
                f"; of the 100 worst, {int(sticking[worst].sum())} sticking, {int(loaded[worst].sum())} loaded")
        if first_worst is None:
            first_worst = set(worst.tolist())
        else:
            line += f"; {len(first_worst & set(worst.tolist()))} of them among the first file's 100 worst"
        print(line)


if __name__ == "__main__":
    main()
