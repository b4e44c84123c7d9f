"""Rotations of single frames in numpy: quaternions, matrices, roll-pitch-yaw, axis-angle, log.

Quaternion convention (the whole project): ``[w, x, y, z]``, unit norm, Hamilton product,
``q_a_b`` rotates vectors of frame b into frame a (``v_a = R(q_a_b) v_b``).
Pinocchio's free-flyer configuration stores ``[x, y, z, w]``; convert only at that boundary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """Cross-product matrix ``[v]x`` with ``[v]x u = v x u``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def quat_multiply(q1: ArrayLike, q2: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``q1 ⊗ q2`` of ``[w, x, y, z]`` quaternions; stacks (..., 4) broadcast row-wise."""
    w1, x1, y1, z1 = np.moveaxis(np.asarray(q1, dtype=float), -1, 0)
    w2, x2, y2, z2 = np.moveaxis(np.asarray(q2, dtype=float), -1, 0)
    return np.stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], axis=-1)


def quat_to_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a ``[w, x, y, z]`` quaternion (normalised first); a stack (..., 4) gives (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    unit = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = unit if q.ndim == 1 else np.moveaxis(unit, -1, 0)  # one quaternion: no axis shuffling
    R = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    return R if q.ndim == 1 else np.moveaxis(R, (0, 1), (-2, -1))


def matrix_to_quat(R: ArrayLike) -> NDArray[np.float64]:
    """``[w, x, y, z]`` quaternion (w ≥ 0) of a rotation matrix (Shepperd's method)."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array([0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s])
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = np.array([(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s])
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = np.array([(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = np.array([(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def rpy_to_matrix(rpy_rad: ArrayLike) -> NDArray[np.float64]:
    """URDF roll-pitch-yaw (fixed axes x, then y, then z): ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = np.asarray(rpy_rad, dtype=float)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def axis_angle_to_matrix(axis: ArrayLike, angle_rad: float) -> NDArray[np.float64]:
    """Rodrigues' formula for a rotation of ``angle_rad`` about unit ``axis``."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    K = skew(k)
    return np.eye(3) + np.sin(angle_rad) * K + (1.0 - np.cos(angle_rad)) * (K @ K)


# rotation angles above π − this use the symmetric part of R for the axis: there the antisymmetric part,
# sin θ · u, has lost the digits (its norm is ~ the distance to π)
_LOG_NEAR_PI_RAD = 1e-3


def rotation_log(R: ArrayLike) -> NDArray[np.float64]:
    """Rotation vectors ``φ = θ u`` [rad] with ``R = exp([φ]×)`` for a stack of rotations (..., 3, 3).

    θ = atan2(‖v‖, (tr R − 1)/2) with ``v = vee(R − Rᵀ)/2 = sin θ · u``: full precision for small angles,
    where arccos of the trace is not; near π the axis comes from ``(R + Rᵀ)/2 − cos θ I = (1 − cos θ) u uᵀ``.
    Vectorised twin of pinocchio's ``log3`` (its oracle in the tests).
    """
    R = np.asarray(R, dtype=float)
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    theta = np.arctan2(s, c)
    # θ / sin θ, with its series where sin θ underflows the division
    small = s < 1e-6
    factor = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, s))
    phi = factor[..., None] * v
    near_pi = theta > np.pi - _LOG_NEAR_PI_RAD
    if np.any(near_pi):
        Rn, cn, vn = R[near_pi], c[near_pi], v[near_pi]
        B = 0.5 * (Rn + np.swapaxes(Rn, -1, -2)) - cn[:, None, None] * np.eye(3)
        col = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        u = B[np.arange(len(col)), :, col]
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        u *= np.where(np.einsum("ni,ni->n", u, vn) < 0.0, -1.0, 1.0)[:, None]  # the sign sin θ · u carries
        phi[near_pi] = theta[near_pi, None] * u
    return phi
