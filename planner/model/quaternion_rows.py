"""Quaternion operations on stacks of rows ((n, 4) ``[w, x, y, z]``); the product of stacks is
:func:`planner.model.rotation.quat_multiply`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def quats_to_matrices(q_wxyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 4) unit quaternions → (n, 3, 3) rotation matrices (same formula as ``quat_to_matrix``)."""
    w, x, y, z = q_wxyz.T
    R = np.empty((q_wxyz.shape[0], 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def quat_exp_pure_rows(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``exp([0, v])`` for (n, 3) ``v`` [rad]: ``[cos‖v‖, sin‖v‖ v/‖v‖]``, smooth at ``v = 0``."""
    angle = np.linalg.norm(v, axis=-1)
    # np.sinc(x) = sin(πx)/(πx): avoids the 0/0 at zero rotation without a branch.
    sin_over_angle = np.sinc(angle / np.pi)
    return np.concatenate([np.cos(angle)[:, None], sin_over_angle[:, None] * v], axis=-1)


def matrices_to_quats(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 3, 3) rotation matrices → (n, 4) unit quaternions ``[w, x, y, z]`` with w ≥ 0 (Shepperd's method, the
    branch of ``matrix_to_quat`` chosen row by row)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    r00, r11, r22 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    tr = r00 + r11 + r22
    q = np.empty((len(R), 4))
    branches = (tr > 0, (r00 > r11) & (r00 > r22), r11 > r22, np.ones(len(R), dtype=bool))
    taken = np.zeros(len(R), dtype=bool)
    for b, cond in enumerate(branches):
        rows = cond & ~taken
        taken |= rows
        if rows.any():
            q[rows] = _shepperd_branch(R[rows], b)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[:, :1] >= 0, q, -q)


def _shepperd_branch(R: NDArray[np.float64], branch: int) -> NDArray[np.float64]:
    """Shepperd's quaternion of (m, 3, 3) matrices by its ``branch`` (0: trace, 1/2/3: largest diagonal x/y/z)."""
    r = np.moveaxis(R, 0, -1)  # r[i, j] is the (m,) column of entry (i, j)
    if branch == 0:
        s = 2.0 * np.sqrt(r[0, 0] + r[1, 1] + r[2, 2] + 1.0)
        return np.stack([0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s], -1)
    if branch == 1:
        s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        return np.stack([(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s], -1)
    if branch == 2:
        s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        return np.stack([(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s], -1)
    s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
    return np.stack([(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s], -1)
