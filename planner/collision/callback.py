"""Signed distances of a collision scene at many via points as one CasADi function, with exact gradients.

IPOPT needs the collision constraints (Eq. 19) and their first derivatives; the distance engine is not
symbolic, so the distances enter the NLP through a :class:`casadi.Callback`. Its input is the world pose of
every frame at every via point, ``[vec(R_world_frame) (9, column-major), p_world_frame (3)]`` per frame and
point (a body moves with its frame, see :class:`~planner.collision.layout.CollisionBody`); its output is every
pair's distance at every point, point-major. One call sweeps all points at once (the engine is vectorised
over poses). The Jacobian comes from the witness points (TrajOpt style): with the witness point a held
fixed in body A (local coordinates ``a = R_Aᵀ (p_a − p_A)``) and n the unit normal, ``∂d/∂p_A = −n``,
``∂d/∂R_A[i, j] = −n_i a_j`` (and + for body B). CasADi chains this through the symbolic kinematics and the
base integration, so the NLP gets exact first derivatives of d wherever the witness pair is unique (d is
differentiable there for convex shapes).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence

import casadi as ca
import numpy as np

from planner.collision.scene_distances import CollisionScene, PairSweep
from planner.model.freefloating import quat_to_rotation_sym

POSE_SIZE = 12  # vec(R) column-major (9) + p (3)
# Sweeps kept per callback, keyed by the exact input: IPOPT evaluates the constraints at a trial point and,
# once it is accepted, their Jacobian there, and CasADi's Jacobian call re-evaluates the values too.
SWEEP_CACHE_SIZE = 64


class _DistanceJacobian(ca.Callback):
    """The Jacobian of :class:`SceneDistanceCallback`: its structural nonzeros, from the witnesses and normals."""

    def __init__(self, owner: SceneDistanceCallback, name: str, opts: dict) -> None:
        ca.Callback.__init__(self)
        self.owner = owner
        self.construct(name, opts)

    def get_n_in(self) -> int:
        return 2

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.owner.n_x, 1) if i == 0 else ca.Sparsity.dense(self.owner.n_out, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self.owner.jac_sparsity

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: tuple, res: tuple) -> int:
        np.frombuffer(res[0], dtype=np.float64)[:] = self.owner.jacobian_nonzeros(np.frombuffer(arg[0], np.float64))
        return 0


class SceneDistanceCallback(ca.Callback):
    """``d = f(poses)``: signed distances [m] of every pair of ``scene`` at ``n_points`` via points.

    ``frame_order`` fixes where each frame's pose sits in a point's block of the input vector.
    """

    def __init__(self, name: str, scene: CollisionScene, frame_order: Sequence[str], n_points: int = 1) -> None:
        ca.Callback.__init__(self)
        self.scene = scene
        self.frames = list(frame_order)
        self.n_points = int(n_points)
        self.n_frames = len(self.frames)
        self.n_pairs = len(scene.pairs)
        self.n_x = POSE_SIZE * self.n_frames * self.n_points
        self.n_out = self.n_pairs * self.n_points
        index = {f: i for i, f in enumerate(self.frames)}
        self._frame_a = np.array([index[scene.frame_of(a)] for a, _ in scene.pairs])
        self._frame_b = np.array([index[scene.frame_of(b)] for _, b in scene.pairs])
        self._build_sparsity()
        self._cache: OrderedDict[bytes, PairSweep] = OrderedDict()
        self._jac: _DistanceJacobian | None = None
        self.construct(name, {"enable_fd": False})

    def _build_sparsity(self) -> None:
        """Row (point, pair) depends on the 12 pose entries of its two frames at that point."""
        rows, cols = [], []
        for j in range(self.n_points):
            for k in range(self.n_pairs):
                for frame in (self._frame_a[k], self._frame_b[k]):
                    start = POSE_SIZE * (j * self.n_frames + frame)
                    rows += [j * self.n_pairs + k] * POSE_SIZE
                    cols += list(range(start, start + POSE_SIZE))
        self.jac_sparsity = ca.Sparsity.triplet(self.n_out, self.n_x, rows, cols)
        # (row, column) of each structural nonzero, in CasADi's column-major order
        self.jac_rows, self.jac_cols = (np.asarray(a) for a in self.jac_sparsity.get_triplet())

    def get_n_in(self) -> int:
        return 1

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.n_x, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.n_out, 1)

    def _blocks(self, x: np.ndarray) -> np.ndarray:
        """The input as (n_points, n_frames, 12)."""
        return x.reshape(self.n_points, self.n_frames, POSE_SIZE)

    def _sweep(self, x: np.ndarray) -> PairSweep:
        """The scene's sweep at every point of the input, cached by the exact input."""
        key = x.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        sweep = self.scene.sweep(frame_poses(self._blocks(x), self.frames))
        self._cache[key] = sweep
        if len(self._cache) > SWEEP_CACHE_SIZE:
            self._cache.popitem(last=False)
        return sweep

    def evaluate(self, x: np.ndarray, with_jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Distances (n_out,) and, if asked, the dense (n_out, n_x) Jacobian (for tests)."""
        d = self._sweep(x).distance_m.ravel()
        if not with_jacobian:
            return d, None
        jac = np.zeros((self.n_out, self.n_x))
        jac[self.jac_rows, self.jac_cols] = self.jacobian_nonzeros(x)
        return d, jac

    def jacobian_nonzeros(self, x: np.ndarray) -> np.ndarray:
        """The Jacobian's structural nonzeros in CasADi's order (witness-point gradients, module docstring)."""
        sweep = self._sweep(x)
        blocks = self._blocks(x)
        values = np.zeros((self.n_points, self.n_pairs, self.n_frames, POSE_SIZE))
        points = np.arange(self.n_points)[:, None]
        pairs = np.arange(self.n_pairs)[None, :]
        for frames, witness, sign in ((self._frame_a, sweep.p_world_a, -1.0), (self._frame_b, sweep.p_world_b, 1.0)):
            pose = blocks[:, frames]  # (n_points, n_pairs, 12)
            Rt = pose[..., :9].reshape(self.n_points, self.n_pairs, 3, 3)  # column-major vec(R) read row-major: Rᵀ
            local = np.einsum("pkij,pkj->pki", Rt, witness - pose[..., 9:])  # witness in body coordinates
            # column-major vec(R): entry (i, j) sits at 3 j + i, i.e. the C-order ravel of local ⊗ n
            n = sweep.normal_world
            grad = np.concatenate([(local[..., :, None] * n[..., None, :]).reshape(self.n_points, self.n_pairs, 9),
                                   n], axis=-1)
            values[points, pairs, frames[None, :]] += sign * grad
        dense_rows = self.jac_rows // self.n_pairs, self.jac_rows % self.n_pairs
        col_frame = (self.jac_cols // POSE_SIZE) % self.n_frames
        return values[dense_rows[0], dense_rows[1], col_frame, self.jac_cols % POSE_SIZE]

    # CasADi hands the callbacks their raw buffers (eval_buffer): no conversion between DM and numpy per call
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


def frame_poses(blocks: np.ndarray, frames: Sequence[str]) -> dict[str, np.ndarray]:
    """Pose blocks ``(n_points, n_frames, 12)`` (:func:`pose_vector` each) as ``frame → (n_points, 4, 4)``."""
    n_points, n_frames = blocks.shape[:2]
    T = np.tile(np.eye(4), (n_points, n_frames, 1, 1))
    T[:, :, :3, :3] = blocks[:, :, :9].reshape(n_points, n_frames, 3, 3).swapaxes(2, 3)
    T[:, :, :3, 3] = blocks[:, :, 9:]
    return {f: T[:, i] for i, f in enumerate(frames)}


def pose_vector(R: ca.SX | ca.MX | ca.DM, p: ca.SX | ca.MX | ca.DM) -> ca.SX | ca.MX | ca.DM:
    """``[vec(R) column-major; p]`` — the per-frame block of the callback input."""
    return ca.vertcat(ca.reshape(R, 9, 1), p)


def chaser_pose_blocks(fk_out: Sequence[ca.SX], n_bodies: int, x_base: ca.SX) -> tuple[list[ca.SX], ca.SX]:
    """The chaser's ``n_bodies`` body frames in the world as callback blocks (:func:`pose_vector` each), from
    :func:`planner.model.robot.fk_function`'s base-frame outputs ``fk_out`` and the base state ``x_base``
    ``[p_world_base (3) [m], quat_world_base (4)]``; ``(blocks, R_world_base)``."""
    R_wb = quat_to_rotation_sym(x_base[3:7])
    blocks = [pose_vector(ca.mtimes(R_wb, fk_out[2 * i]), x_base[:3] + ca.mtimes(R_wb, fk_out[2 * i + 1]))
              for i in range(n_bodies)]
    return blocks, R_wb
