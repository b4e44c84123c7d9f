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
