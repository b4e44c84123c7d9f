"""CasADi kinematics of the chaser against pinocchio (the oracle), and URDF parsing."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from planner.model.robot import fk_function, pin_configuration
from planner.model.rotation import quat_to_matrix
from planner.model.shapes import Box, Capsule


def _random_base(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    quat = rng.normal(size=4)
    return rng.uniform(-2, 2, size=3), quat / np.linalg.norm(quat)


def test_default_robot_structure(robot):
    assert robot.body_names == ("base_link", *(f"link{i}" for i in range(1, 8)))
    assert robot.n_joints == 7
    assert 850 < robot.total_mass_kg < 900
    assert isinstance(robot.collision_shapes[0][0].shape, Box)
    assert all(isinstance(s[0].shape, Capsule) for s in robot.collision_shapes[1:])
    # alternating ±170° / ±120° limits, 20 °/s velocity limits (the paper's scenarios)
    np.testing.assert_allclose(np.degrees(robot.q_max), [170, 120, 170, 120, 170, 120, 170])
    np.testing.assert_allclose(np.degrees(robot.qd_max), 20.0)


def test_casadi_fk_matches_pinocchio_at_100_random_configurations(robot):
    fk = fk_function(robot)
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(1)
    frame_ids = [model.getFrameId(b) for b in robot.body_names] + [model.getFrameId(robot.ee_frame)]
    worst = 0.0
    for _ in range(100):
        q = rng.uniform(robot.q_min, robot.q_max)
        p_base, quat = _random_base(rng)
        R_base = quat_to_matrix(quat)
        out = fk(q)
        pin.framesForwardKinematics(model, data, pin_configuration(p_base, quat, q))
        for k, fid in enumerate(frame_ids):
            R_world = R_base @ np.array(out[2 * k])
            p_world = p_base + R_base @ np.array(out[2 * k + 1]).ravel()
            oMf = data.oMf[fid]
            worst = max(worst, np.abs(R_world - oMf.rotation).max(), np.abs(p_world - oMf.translation).max())
    assert worst <= 1e-10


def test_payload_inertia_matches_pinocchio_appended_body(robot):
    """with_payload adds the target to the last link exactly as pinocchio's inertia algebra does."""
    from planner.model.robot import BodyInertia

    payload = BodyInertia(1500.0, np.array([0.1, -0.2, 0.3]), np.diag([5000.0, 3000.0, 7000.0]))
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix([0.9, 0.1, -0.3, 0.2])
    T[:3, 3] = [0.0, 0.5, 1.7]
    compound = robot.with_payload(payload, T)
    jid = compound.pin_model.njoints - 1
    I_pin = compound.pin_model.inertias[jid]
    last = compound.inertias[-1]
    assert abs(last.mass_kg - I_pin.mass) < 1e-9
    np.testing.assert_allclose(last.com_body_m, I_pin.lever, atol=1e-12)
    np.testing.assert_allclose(last.inertia_com_kg_m2, I_pin.inertia, atol=1e-8)
    assert abs(compound.total_mass_kg - robot.total_mass_kg - 1500.0) < 1e-9
