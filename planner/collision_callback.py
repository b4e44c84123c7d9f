"""Signed distances of a collision scene as a CasADi function with exact witness-point gradients.

IPOPT needs the collision constraints (Eq. 19) and their first derivatives; coal is not
symbolic, so the distances enter the NLP through a :class:`casadi.Callback` whose input is the world
pose of every frame at one via point, ``[vec(R_world_frame) (9, column-major), p_world_frame (3)]`` per
frame (a body moves with its frame, see :class:`~planner.collision.CollisionBody`), and whose Jacobian
comes from the witness points (TrajOpt style): with the witness point a held
fixed in body A (local coordinates ``a = R_Aᵀ (p_a − p_A)``) and n the unit normal,
``∂d/∂p_A = −n``, ``∂d/∂R_A[i, j] = −n_i a_j`` (and + for body B). CasADi chains this through the
symbolic kinematics and the base integration, so the NLP gets exact first derivatives of d wherever the
witness pair is unique (d is differentiable there for convex shapes).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence

import casadi as ca
import numpy as np

from planner.collision import CollisionScene

POSE_SIZE = 12  # vec(R) column-major (9) + p (3)
# Sweeps kept per callback, keyed by the exact input: IPOPT evaluates the constraints at a trial point and,
# once it is accepted, their Jacobian there, and CasADi's Jacobian call re-evaluates the values too; one
# NLP evaluation queries up to ~70 pose sets, so a few hundred entries catch every repeat.
SWEEP_CACHE_SIZE = 512


def _poses(frames: Sequence[str], x: np.ndarray) -> dict[str, np.ndarray]:
    T = {}
    for i, name in enumerate(frames):
        block = x[POSE_SIZE * i: POSE_SIZE * (i + 1)]
        Ti = np.eye(4)
        Ti[:3, :3] = block[:9].reshape(3, 3, order="F")
        Ti[:3, 3] = block[9:]
        T[name] = Ti
    return T


class _DistanceJacobian(ca.Callback):
    def __init__(self, owner: SceneDistanceCallback, name: str, opts: dict) -> None:
        ca.Callback.__init__(self)
        self.owner = owner
        self.construct(name, opts)

    def get_n_in(self) -> int:
        return 2

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.owner.n_x, 1) if i == 0 else ca.Sparsity.dense(self.owner.n_pairs, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self.owner.jac_sparsity

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: tuple, res: tuple) -> int:
        _, jac = self.owner.evaluate(np.frombuffer(arg[0], dtype=np.float64), with_jacobian=True)
        np.frombuffer(res[0], dtype=np.float64)[:] = jac[self.owner.jac_rows, self.owner.jac_cols]
        return 0


class SceneDistanceCallback(ca.Callback):
    """``d = f(poses)``: signed distances (m) of every pair of ``scene`` at one via point.

    ``frame_order`` fixes where each frame's pose sits in the input vector.
    """

    def __init__(self, name: str, scene: CollisionScene, frame_order: Sequence[str]) -> None:
        ca.Callback.__init__(self)
        self.scene = scene
        self.body_order = list(frame_order)
        self.index = {b: i for i, b in enumerate(self.body_order)}
        self.n_x = POSE_SIZE * len(self.body_order)
        self.n_pairs = len(scene.pairs)
        rows, cols = [], []
        for k, (a, b) in enumerate(scene.pairs):
            for body in (a, b):
                start = POSE_SIZE * self.index[scene.frame_of(body)]
                rows += [k] * POSE_SIZE
                cols += list(range(start, start + POSE_SIZE))
        self.jac_sparsity = ca.Sparsity.triplet(self.n_pairs, self.n_x, rows, cols)
        # (row, column) of each structural nonzero, in CasADi's column-major order
        self.jac_rows, self.jac_cols = (np.asarray(a) for a in self.jac_sparsity.get_triplet())
        self._body_a = np.array([self.index[scene.frame_of(a)] for a, _ in scene.pairs])
        self._body_b = np.array([self.index[scene.frame_of(b)] for _, b in scene.pairs])
        self._cache: OrderedDict[bytes, tuple[np.ndarray, ...]] = OrderedDict()
        self._jac: _DistanceJacobian | None = None
        self.construct(name, {"enable_fd": False})

    def get_n_in(self) -> int:
        return 1

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.n_x, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.n_pairs, 1)

    def _sweep(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Distances (m), witness points on A and B and unit normals (world) of every pair, cached."""
        key = x.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        sweep = self.scene.distance_arrays(_poses(self.body_order, x))
        self._cache[key] = sweep
        if len(self._cache) > SWEEP_CACHE_SIZE:
            self._cache.popitem(last=False)
        return sweep

    def evaluate(self, x: np.ndarray, with_jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Distances (n_pairs,) and, if asked, the (n_pairs, n_x) Jacobian as a dense array."""
        d, PA, PB, N = self._sweep(x)
        if not with_jacobian:
            return d, None
        blocks = x.reshape(-1, POSE_SIZE)
        Rt = blocks[:, :9].reshape(-1, 3, 3)  # the column-major vec(R) read row-major is Rᵀ
        jac = np.zeros((self.n_pairs, self.n_x))
        rows = np.arange(self.n_pairs)[:, None]
        for body, point, sign in ((self._body_a, PA, -1.0), (self._body_b, PB, 1.0)):
            local = np.einsum("kij,kj->ki", Rt[body], point - blocks[body, 9:])  # witness in body coordinates
            # column-major vec(R): entry (i, j) sits at 3 j + i, i.e. the C-order ravel of local ⊗ n
            cols = POSE_SIZE * body[:, None] + np.arange(POSE_SIZE)
            jac[rows, cols] = sign * np.concatenate([(local[:, :, None] * N[:, None, :]).reshape(-1, 9), N], axis=1)
        return d, jac

    # CasADi hands the callbacks their raw buffers (eval_buffer): converting a DM to numpy and back cost ~40 µs
    # per call, ~0.5 s of a scenario II plan's 9000 calls
    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: tuple, res: tuple) -> int:
        np.frombuffer(res[0], dtype=np.float64)[:] = self.evaluate(np.frombuffer(arg[0], dtype=np.float64))[0]
        return 0

    def has_jacobian(self) -> bool:
        return True

    def get_jacobian(self, name: str, inames: list, onames: list, opts: dict) -> ca.Function:
        self._jac = _DistanceJacobian(self, name, opts)
        return self._jac


def pose_vector(R, p):  # noqa: ANN001, ANN201 - SX/MX/DM in, same out
    """``[vec(R) column-major; p]`` — the per-body block of the callback input."""
    return ca.vertcat(ca.reshape(R, 9, 1), p)
