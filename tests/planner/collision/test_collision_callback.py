"""The NLP's collision constraint (planner.collision.callback): values, witness-point Jacobian, sweep cache."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from planner.collision.callback import SceneDistanceCallback, pose_vector
from planner.collision.layout import TARGET_BODY
from planner.collision.nlp_scene import build_scene, world_poses
from planner.config.scenario import load_scenario
from planner.model.robot import fk_function
from planner.model.rotation import quat_to_matrix

SCENARIO_I = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_I.toml"


@pytest.fixture(scope="module")
def chain():
    """d(q): the scenario's pair distances as the NLP builds them, arm joints → FK → callback."""
    sc = load_scenario(SCENARIO_I)
    robot = sc.robot
    scene = build_scene(sc)
    cb = SceneDistanceCallback("test_distance", scene, [*robot.body_names, TARGET_BODY])
    fk = fk_function(robot)
    R_target = quat_to_matrix([0.9, 0.2, -0.3, 0.1])
    q = ca.MX.sym("q", robot.n_joints)
    out = fk(q)
    blocks = [pose_vector(out[2 * i], out[2 * i + 1]) for i in range(len(robot.body_names))]
    blocks.append(pose_vector(ca.DM(R_target), ca.DM(sc.target.p_world_com)))
    d = cb(ca.vertcat(*blocks))
    f = ca.Function("d_of_q", [q], [d, ca.jacobian(d, q)])
    return sc, scene, cb, fk, R_target, f


def _random_configurations(sc, count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.7 * sc.robot.q_min, 0.7 * sc.robot.q_max, size=(count, sc.robot.n_joints))


def test_values_equal_the_scene_sweep(chain):
    """Oracle: CollisionScene.distances on the same world poses, built without CasADi."""
    sc, scene, _, fk, R_target, f = chain
    T_target = np.eye(4)
    T_target[:3, :3] = R_target
    T_target[:3, 3] = sc.target.p_world_com
    for q in _random_configurations(sc, 10, 1):
        poses = world_poses(sc.robot, fk(q), np.eye(3), np.zeros(3), T_target)
        expected = [r.distance_m for r in scene.distances(poses)]
        np.testing.assert_allclose(np.asarray(f(q)[0]).ravel(), expected, rtol=0, atol=1e-12)


def test_jacobian_through_the_kinematics_matches_central_differences(chain):
    """The witness-point Jacobian, chained by CasADi through the symbolic FK, against central differences
    of the distances in joint space (h = 1e-6 rad). The engine is closed form, exact to rounding, so 1e-5
    relative per pair is a real bound (FD truncation ~h²)."""
    sc, _, _, _, _, f = chain
    h = 1e-6
    checked = 0
    for q in _random_configurations(sc, 8, 2):
        d, J = (np.asarray(a) for a in f(q))
        fd = np.empty_like(J)
        for j in range(len(q)):
            e = np.zeros(len(q))
            e[j] = h
            fd[:, j] = (np.asarray(f(q + e)[0]).ravel() - np.asarray(f(q - e)[0]).ravel()) / (2 * h)
        scale = np.maximum(np.linalg.norm(fd, axis=1), 1e-3)
        np.testing.assert_array_less(np.linalg.norm(J - fd, axis=1) / scale, 1e-5)
        checked += int((np.linalg.norm(fd, axis=1) > 1e-3).sum())
    assert checked >= 100  # most arm pairs move with q; base-target pairs have zero gradient on both sides


def test_sweep_cache_returns_each_input_its_own_distances(chain):
    """Alternating inputs must never be served another input's cached sweep, and a cached Jacobian
    equals one computed by a callback that has never seen the input."""
    sc, scene, cb, _, _, f = chain
    qs = _random_configurations(sc, 3, 3)
    first = [np.asarray(f(q)[0]).ravel() for q in qs]
    for _ in range(2):
        for q, d in zip(qs, first, strict=True):
            np.testing.assert_array_equal(np.asarray(f(q)[0]).ravel(), d)
    fresh = SceneDistanceCallback("fresh_distance", scene, cb.frames)
    x = np.random.default_rng(4).normal(size=cb.n_x)
    x.reshape(-1, 12)[:, :9] = np.stack([quat_to_matrix(v).ravel(order="F") for v in
                                         np.random.default_rng(5).normal(size=(len(cb.frames), 4))])
    cb.evaluate(x)  # fills the cache; the Jacobian below is assembled from the cached sweep
    d_cached, J_cached = cb.evaluate(x, with_jacobian=True)
    d_fresh, J_fresh = fresh.evaluate(x, with_jacobian=True)
    np.testing.assert_array_equal(d_cached, d_fresh)
    np.testing.assert_array_equal(J_cached, J_fresh)


def test_many_points_in_one_call_equal_one_point_at_a_time(chain):
    """The NLPs sweep every via point in one call: values and Jacobian blocks equal the one-point callback's."""
    sc, scene, cb, fk, R_target, _ = chain
    n = 3
    many = SceneDistanceCallback("test_distance_many", scene, cb.frames, n)
    xs = []
    for q in _random_configurations(sc, n, 4):
        out = fk(q)
        blocks = [np.asarray(pose_vector(out[2 * i], out[2 * i + 1])).ravel() for i in range(len(sc.robot.body_names))]
        blocks.append(np.asarray(pose_vector(ca.DM(R_target), ca.DM(sc.target.p_world_com))).ravel())
        xs.append(np.concatenate(blocks))
    d_many, J_many = many.evaluate(np.concatenate(xs), with_jacobian=True)
    m, nx = cb.n_out, cb.n_x
    for j, x in enumerate(xs):
        d_one, J_one = cb.evaluate(x, with_jacobian=True)
        np.testing.assert_array_equal(d_many[j * m: (j + 1) * m], d_one)
        np.testing.assert_array_equal(J_many[j * m: (j + 1) * m, j * nx: (j + 1) * nx], J_one)
        off_block = np.delete(J_many[j * m: (j + 1) * m], np.s_[j * nx: (j + 1) * nx], axis=1)
        assert not off_block.any()
