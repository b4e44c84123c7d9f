"""The compound chaser + target with its grasp geometry as parameters (planner.model.compound), against pinocchio's
compound model (``RobotModel.with_payload``) at several grasps: one symbolic model must serve them all."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from planner.config.scenario import load_scenario
from planner.model.compound import GEOMETRY_SIZE, GraspGeometry, compound_robot, grasp_geometry
from planner.model.freefloating import FreeFloatingModel, base_twist_sym, momentum_map, rk4_step_function
from planner.model.robot import pin_configuration
from planner.model.rotation import axis_angle_to_matrix, quat_to_matrix

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(ROOT / "configs" / "scenarios" / "scenario_II.toml")


def _grasps(scenario) -> list[np.ndarray]:
    """T_ee_target of the scenario's grasp at three free-axis angles (rad)."""
    T_bg = scenario.target.grasp.T_body_grasp
    axis = scenario.target.grasp.free_axis
    result = []
    for psi in (0.0, 1.1, -2.4):
        T = T_bg.copy()
        T[:3, :3] = T[:3, :3] @ axis_angle_to_matrix(axis, psi)
        result.append(np.linalg.inv(T))
    return result


@pytest.fixture(scope="module")
def symbolic(scenario_II):
    """``base_twist(q, qd, h_base, geometry)`` of the compound written in the geometry symbols."""
    robot = scenario_II.robot
    q, qd, h = (ca.SX.sym(name, size) for name, size in (("q", 7), ("qd", 7), ("h", 6)))
    geometry = ca.SX.sym("geometry", GEOMETRY_SIZE)
    mm = momentum_map(GraspGeometry.unpack(geometry).compound(robot), q)
    return ca.Function("twist", [q, qd, h, geometry], [base_twist_sym(mm, qd, h)])


def test_geometry_vector_holds_the_compound_last_link_and_the_grasp(scenario_II):
    T = _grasps(scenario_II)[1]
    g = grasp_geometry(scenario_II, T)
    assert g.shape == (GEOMETRY_SIZE,)
    chaser_last = scenario_II.robot.inertias[-1]
    assert g[0] == pytest.approx(chaser_last.mass_kg + scenario_II.target.mass_kg, rel=1e-15)
    assert g[13] == scenario_II.target.mass_kg
    np.testing.assert_array_equal(g[23:26], T[:3, 3])
    np.testing.assert_array_equal(g[26:35].reshape(3, 3, order="F"), T[:3, :3])
    np.testing.assert_array_equal(g[14:23].reshape(3, 3, order="F"), scenario_II.target.inertia_body_kg_m2)


def test_one_symbolic_compound_gives_pinocchio_momentum_at_every_grasp(scenario_II, symbolic):
    """The base twist of the parametrised compound carries exactly the momentum pinocchio's compound model
    (the target's inertia added to the last link) computes, at grasps 3.5 rad apart around the free axis."""
    rng = np.random.default_rng(7)
    robot = scenario_II.robot
    h_world = np.array([40.0, -15.0, 8.0, 900.0, -300.0, 2500.0])
    for T in _grasps(scenario_II):
        model = compound_robot(scenario_II, T).pin_model
        data = model.createData()
        g = grasp_geometry(scenario_II, T)
        for _ in range(10):
            q = rng.uniform(robot.q_min, robot.q_max)
            qd = rng.uniform(-1, 1, 7) * robot.qd_max
            quat = rng.normal(size=4)
            quat /= np.linalg.norm(quat)
            R = quat_to_matrix(quat)
            h_base = np.concatenate([R.T @ h_world[:3], R.T @ h_world[3:]])
            twist = np.asarray(symbolic(q, qd, h_base, g)).ravel()
            A_g = pin.computeCentroidalMap(model, data, pin_configuration(np.zeros(3), quat, q))
            np.testing.assert_allclose(A_g @ np.concatenate([twist, qd]), h_world, atol=1e-9 * np.abs(h_world).max())


def test_parametrised_rk4_step_equals_the_numeric_compound_step(scenario_II):
    robot = scenario_II.robot
    geometry = ca.SX.sym("geometry", GEOMETRY_SIZE)
    step = rk4_step_function(GraspGeometry.unpack(geometry).compound(robot), geometry)
    rng = np.random.default_rng(8)
    x = np.concatenate([[0.1, -0.2, 0.3], np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2])])
    joints = [rng.uniform(-1, 1, 7) for _ in range(6)]
    h = np.array([40.0, -15.0, 8.0, 900.0, -300.0, 2500.0])
    for T in _grasps(scenario_II):
        numeric = FreeFloatingModel(compound_robot(scenario_II, T)).rk4_step(x, *joints, h, 0.25)
        np.testing.assert_allclose(np.asarray(step(x, *joints, h, 0.25, grasp_geometry(scenario_II, T))),
                                   np.asarray(numeric), rtol=0, atol=1e-13)


def test_dense_resimulation_with_the_compiled_parametric_step_follows_the_numeric_compound(scenario_II):
    """A compound model given the compiled parametric step (``parametric_rk4``, what a plan's stabilization
    re-simulation uses) integrates the same base poses as the numeric compound's own step, over 200 RK4 steps
    of a seeded joint motion at each grasp; the compiled step is made once per robot object."""
    from planner.phases.stabilization_dynamics import compound_rk4_step

    robot = scenario_II.robot
    step = compound_rk4_step(robot)
    assert compound_rk4_step(robot) is step
    t = np.linspace(0.0, 10.0, 201)
    mids = 0.5 * (t[:-1] + t[1:])
    a = np.random.default_rng(9).uniform(-0.3, 0.3, 7)
    q, qd = np.outer(np.sin(t), a), np.outer(np.cos(t), a)
    q_mid, qd_mid = np.outer(np.sin(mids), a), np.outer(np.cos(mids), a)
    x0 = np.array([0.5, 0.0, -0.2, 1.0, 0.0, 0.0, 0.0])
    h = np.array([40.0, -15.0, 8.0, 900.0, -300.0, 2500.0])
    for T in _grasps(scenario_II):
        numeric = FreeFloatingModel(compound_robot(scenario_II, T))
        fast = FreeFloatingModel(compound_robot(scenario_II, T), parametric_rk4=(step, grasp_geometry(scenario_II, T)))
        x_ref = numeric.integrate_base_sampled(t, q, qd, q_mid, qd_mid, x0, h)
        x_fast = fast.integrate_base_sampled(t, q, qd, q_mid, qd_mid, x0, h)
        assert np.abs(x_ref[-1] - x0).max() > 1e-2  # the base really moves
        np.testing.assert_allclose(x_fast, x_ref, rtol=0, atol=1e-12)


def test_grasp_wrench_equals_newton_euler_on_pinocchio_accelerations(scenario_II):
    """The stabilization's grasp wrench (one Function, geometry as a parameter) against an independent route:
    pinocchio's compound model, the base acceleration that keeps the centroidal momentum constant
    (``A_g a + Ȧ_g v = 0``), the target COM's classical acceleration from pinocchio's frame kinematics,
    then Newton-Euler on the target (force, and moment about the grasp point, both in the grasp frame)."""
    from planner.phases.stabilization import wrench_function

    robot = scenario_II.robot
    target = scenario_II.target
    wrench = wrench_function(robot)
    rng = np.random.default_rng(11)
    h_world = np.array([40.0, -15.0, 8.0, 900.0, -300.0, 2500.0])
    for T in _grasps(scenario_II):
        compound = compound_robot(scenario_II, T)
        model = compound.pin_model.copy()
        ee = model.frames[model.getFrameId(robot.ee_frame)]
        placement = ee.placement * pin.SE3(T[:3, :3], T[:3, 3])
        fid = model.addFrame(pin.Frame("target_com", ee.parentJoint, placement, pin.FrameType.OP_FRAME))
        fid_ee = model.getFrameId(robot.ee_frame)
        data = model.createData()
        ff = FreeFloatingModel(compound)
        g = grasp_geometry(scenario_II, T)
        for _ in range(4):
            q = rng.uniform(robot.q_min, robot.q_max)
            qd = rng.uniform(-1, 1, 7) * robot.qd_max
            qdd = rng.uniform(-1, 1, 7) * 0.2
            quat = rng.normal(size=4)
            quat /= np.linalg.norm(quat)
            p = rng.uniform(-1, 1, 3)
            R = quat_to_matrix(quat)
            twist = np.asarray(ff.base_twist(q, qd, np.concatenate([R.T @ h_world[:3], R.T @ h_world[3:]]))).ravel()
            x = pin_configuration(p, quat, q)
            v = np.concatenate([twist, qd])
            A_g = pin.computeCentroidalMap(model, data, x)
            dA_g = pin.computeCentroidalMapTimeVariation(model, data, x, v)
            a_base = np.linalg.solve(A_g[:, :6], -(A_g[:, 6:] @ qdd + dA_g @ v))
            pin.forwardKinematics(model, data, x, v, np.concatenate([a_base, qdd]))
            pin.updateFramePlacements(model, data)
            frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            acc = pin.getFrameClassicalAcceleration(model, data, fid, frame)
            omega = pin.getFrameVelocity(model, data, fid, frame).angular
            R_T = data.oMf[fid].rotation
            I_world = R_T @ target.inertia_body_kg_m2 @ R_T.T
            F = target.mass_kg * acc.linear
            M = I_world @ acc.angular + np.cross(omega, I_world @ omega)
            M += np.cross(data.oMf[fid].translation - data.oMf[fid_ee].translation, F)
            R_ee = data.oMf[fid_ee].rotation
            out = wrench(np.concatenate([p, quat]), q, qd, qdd, h_world, g)
            scale = max(np.abs(F).max(), np.abs(M).max())
            np.testing.assert_allclose(np.asarray(out[0]).ravel(), R_ee.T @ F, atol=1e-8 * scale)
            np.testing.assert_allclose(np.asarray(out[1]).ravel(), R_ee.T @ M, atol=1e-8 * scale)
