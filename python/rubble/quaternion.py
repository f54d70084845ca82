"""Quaternion order helpers.

rubble's arrays in Python (Simulation.orientations, RunReader.snapshot()["orientations"]) hold unit
quaternions body frame -> world frame as (x, y, z, w): the order Eigen stores Quaterniond's
coefficients in memory (Quaternion::coeffs()), which is what makes Simulation.orientations a view
without a copy, and the order scipy.spatial.transform.Rotation.from_quat expects (scalar last).
The run file (/snapshots/NNNNNN/orientation), the checkpoints' documentation and the scene files
write (w, x, y, z) (scalar first), as h5py shows them.
"""
import numpy as np


def xyzw_to_wxyz(q):
    """(…, 4) quaternions (x, y, z, w) -> (w, x, y, z) (a copy)."""
    q = np.asarray(q)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


def wxyz_to_xyzw(q):
    """(…, 4) quaternions (w, x, y, z) -> (x, y, z, w) (a copy): e.g. a run file's orientations for scipy."""
    q = np.asarray(q)
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def to_rotation_matrices(q_xyzw):
    """(N, 4) quaternions (x, y, z, w) -> (N, 3, 3) rotation matrices (body frame -> world frame)."""
    q = np.asarray(q_xyzw, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def to_scipy(q_xyzw):
    """A scipy Rotation from (N, 4) quaternions (x, y, z, w) (needs scipy)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_quat(np.asarray(q_xyzw))
