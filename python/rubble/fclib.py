"""FCLib local frictional-contact problems (W, q, mu) solved by the simulation's NLGS.

    sol = rubble.fclib.solve("problem.hdf5")                    # = rubble fclib problem.hdf5
    sol = rubble.fclib.solve((W, q, mu), tolerance=1e-10)      # W: scipy.sparse or dense (3nc, 3nc)
    sol["r"], sol["u"], sol["error"], sol["converged"]

Find r, u with u = W r + q and, per contact (normal first), r in the Coulomb cone of mu, Signorini
and Coulomb's law (nlgs_solver/README.md). The error is FCLib's ||F(r)|| / ||q||.
"""
import os

import numpy as np

from ._rubble import _fclib_read, _fclib_solve_csr, _fclib_solve_file


def read(path):
    """Reads an FCLib file: (W, q, mu) with W a scipy.sparse.csr_matrix (or a dict of CSR arrays
    without scipy)."""
    d = _fclib_read(os.fspath(path))
    try:
        from scipy.sparse import csr_matrix
        W = csr_matrix((d["data"], d["indices"], d["indptr"]), shape=d["shape"])
    except ImportError:
        W = {k: d[k] for k in ("indptr", "indices", "data", "shape")}
    return W, d["q"], d["mu"]


def _csr(W):
    """(indptr, indices, data, n) of W: scipy sparse, a CSR dict from read(), or a dense array."""
    if isinstance(W, dict):
        return W["indptr"], W["indices"], W["data"], int(W["shape"][0])
    if hasattr(W, "tocsr"):
        W = W.tocsr().copy()
        W.sum_duplicates()
        W.sort_indices()
        return W.indptr, W.indices, W.data, W.shape[0]
    W = np.asarray(W, dtype=np.float64)
    if W.ndim != 2 or W.shape[0] != W.shape[1]:
        raise ValueError("W: expected a square matrix")
    rows, cols = np.nonzero(W)
    indptr = np.zeros(W.shape[0] + 1, dtype=np.int32)
    np.add.at(indptr, rows + 1, 1)
    return np.cumsum(indptr).astype(np.int32), cols.astype(np.int32), W[rows, cols], W.shape[0]


def solve(problem, tolerance=1e-8, max_iterations=10000, relaxation=1.0, order="as_stored", seed=1,
          polish="newton"):
    """Solves an FCLib problem from r = 0: `problem` is a file path or a tuple (W, q, mu).

    Options as `rubble fclib`: tolerance on ||F||/||q||, max_iterations sweeps, relaxation omega in
    (0, 2), order "as_stored" or "shuffled" (with seed), polish "newton" (default, as the CLI) or
    "none". Returns {"r", "u", "iterations", "newton_iterations", "error", "converged", "contacts",
    "point_residual"}: point_residual[k] is contact k's natural map in velocity units (the measure
    the simulation's residual sums), to see where the error sits.
    Raises FclibFileError for a bad file, ValueError for bad arrays or options.
    """
    args = (float(tolerance), int(max_iterations), float(relaxation), str(order), int(seed), str(polish))
    if isinstance(problem, (str, os.PathLike)):
        return _fclib_solve_file(os.fspath(problem), *args)
    W, q, mu = problem
    indptr, indices, data, n = _csr(W)
    return _fclib_solve_csr(np.asarray(indptr, dtype=np.int32), np.asarray(indices, dtype=np.int32),
                            np.asarray(data, dtype=np.float64), int(n), np.asarray(q, dtype=np.float64).ravel(),
                            np.asarray(mu, dtype=np.float64).ravel(), *args)
