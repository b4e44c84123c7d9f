"""``primitives``: µs per call of the kinematic, momentum and collision building blocks, next to
pinocchio, the time of one dense verification of a whole plan and of one evaluation of each NLP's
constraint Jacobian."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from bench_sections.common import (
    GOLDEN_TABLE,
    Settings,
    load_scenario_named,
    relative,
    stats,
    table_query,
    time_per_call_us,
    timed,
)

if TYPE_CHECKING:
    from planner.model.robot import RobotModel


def _random_configuration(robot: RobotModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint angles inside the limits (rad), base position (m) and attitude quaternion [w, x, y, z]."""
    quat = rng.normal(size=4)
    return rng.uniform(robot.q_min, robot.q_max), rng.uniform(-1.0, 1.0, size=3), quat / np.linalg.norm(quat)


def kinematics(settings: Settings) -> dict[str, Any]:
    """FK of all bodies and momentum map + J*: our CasADi Functions vs pinocchio on the same model."""
    from planner.model.freefloating import FreeFloatingModel
    from planner.model.robot import fk_function, pin_configuration

    robot = load_scenario_named("scenario_II").robot
    q, p_base, quat = _random_configuration(robot, np.random.default_rng(settings.seed))
    x_pin = pin_configuration(p_base, quat, q)
    model = robot.pin_model
    data = model.createData()
    fk = fk_function(robot)
    ff = FreeFloatingModel(robot)

    def pin_fk() -> None:
        pin.forwardKinematics(model, data, x_pin)
        pin.updateFramePlacements(model, data)

    def momentum_and_jstar() -> None:
        ff.momentum(q)
        ff.gen_jacobian(q)

    return {
        "forward_kinematics_casadi_us": time_per_call_us(lambda: fk(q), settings),
        "forward_kinematics_pinocchio_us": time_per_call_us(pin_fk, settings),
        "momentum_map_and_jstar_casadi_us": time_per_call_us(momentum_and_jstar, settings),
        "centroidal_map_pinocchio_us": time_per_call_us(lambda: pin.computeCentroidalMap(model, data, x_pin),
                                                        settings),
        "notes": "CasADi: fk_function (8 bodies + ee, base frame) and FreeFloatingModel.momentum + gen_jacobian "
                 "(A_b, A_m, r_g, J*, D), called from Python with numpy; pinocchio: forwardKinematics + "
                 "updateFramePlacements, and computeCentroidalMap (A_g only, no J*)",
    }


def collision_sweep(settings: Settings) -> dict[str, Any]:
    """Every pair of the approach's scene (37) at a random configuration: the NLPs' engine for one pose set and
    for the approach's 23 via points in one call, and verify's engine over 1000 samples."""
    from planner.collision.layout import scene_layout
    from planner.collision.nlp_scene import build_scene, world_poses
    from planner.model.robot import fk_function
    from planner.model.rotation import quat_to_matrix
    from planner.verify.collision import sweep_pairs

    sc = load_scenario_named("scenario_II")
    rng = np.random.default_rng(settings.seed + 1)
    q, p_base, quat = _random_configuration(sc.robot, rng)
    T_target = np.eye(4)
    T_target[:3, :3] = quat_to_matrix(_random_configuration(sc.robot, rng)[2])
    T_target[:3, 3] = sc.target.p_world_com  # the target where the scenario puts it, randomly turned
    scene = build_scene(sc, gripper_handle=True)
    poses = world_poses(sc.robot, fk_function(sc.robot)(q), quat_to_matrix(quat), p_base, T_target)
    distances = scene.distances(poses)
    via = {name: np.repeat(T[None], 23, axis=0) for name, T in poses.items()}
    samples = {name: np.repeat(T[None], 1000, axis=0) for name, T in poses.items()}
    layout = scene_layout(sc.robot, sc.target)
    second = sweep_pairs(layout, {name: T[None] for name, T in poses.items()}).distance_m[0]
    return {"collision_sweep_us": time_per_call_us(lambda: scene.distances(poses), settings),
            "collision_sweep_23_points_us": time_per_call_us(lambda: scene.sweep(via), settings),
            "collision_verify_1000_samples_s": stats([timed(lambda: sweep_pairs(layout, samples))[1]
                                                      for _ in range(settings.repeats)]),
            "collision_engines_max_difference_m": float(np.max(np.abs(second - [d.distance_m for d in distances]))),
            "collision_pairs": len(scene.pairs),
            "collision_min_distance_m": float(min(d.distance_m for d in distances)),
            "notes_collision": "NLP engine: planner.collision.closed_form (one pose set; 23 via points in one call); "
                               "verify's engine: planner.verify.collision over 1000 samples; python-fcl's "
                               "signed path, replaced, took 161 us for the 29 pairs it had"}


@dataclass(frozen=True)
class GoldenPlan:
    """The golden table's plan of its seed point, re-simulated once for the section: verify and the NLP Jacobians
    both start from it."""

    tq: Any  # the opened golden table (lut.query.table_query.TableQuery)
    point: int
    corners: list[int]
    state: Any  # TargetState
    parameters: Any  # PlanParameters, the start delay within the first spin period
    plan: Any  # GraspPlan
    simulate_s: float


def golden_plan() -> GoldenPlan:
    """Re-simulate the golden table's seed point (interpolation there returns that node's record)."""
    tq = table_query(GOLDEN_TABLE)
    point = tq.grid.seed_point()
    state = tq.grid.state(point)
    found = tq.interpolate(state)
    given = tq.placed(state, found.parameters)  # in the window, as the query starts it (no observation: no timing)
    plan, simulate_s = timed(lambda: tq.planner.simulate(state, given))
    return GoldenPlan(tq, int(point), found.corners, state, given, plan, simulate_s)


def verify_one_plan(settings: Settings, golden: GoldenPlan) -> dict[str, Any]:
    """``planner.verify.verifier.verify`` of a whole plan, the golden table's, timed apart from its simulation."""
    from planner.verify.verifier import DEFAULT_STEP_S, verify

    plan = golden.plan
    runs = []
    for _ in range(settings.verify_runs):
        report, seconds = timed(lambda: verify(plan))
        runs.append(seconds)
    return {"verify_plan_s": stats(runs), "verify_plan_simulate_s": golden.simulate_s,
            "verify_plan": {"table": relative(GOLDEN_TABLE), "grid_point": golden.point, "corners": golden.corners,
                            "plan_samples": int(len(plan.t)), "verify_step_s": DEFAULT_STEP_S,
                            "plan_duration_s": float(plan.t[-1] - plan.t[0]),
                            "feasible": bool(report.feasible)}}


JACOBIAN_CALLS = 20  # evaluations per timed batch of an NLP's constraint Jacobian (tens of ms each)
JACOBIAN_CALLS_TRIMMED = 3


def _jacobian_ms(solver: Any, x: np.ndarray, p: np.ndarray, settings: Settings) -> dict[str, float | int]:
    """ms per evaluation of ``solver``'s constraint Jacobian (with the constraints, as IPOPT asks for them) near
    ``x``: each call at another point, so no distance sweep is reused."""
    jac = solver.get_function("nlp_jac_g")
    jac(x, p)
    calls = JACOBIAN_CALLS_TRIMMED if settings.trim else JACOBIAN_CALLS
    batches = []
    for r in range(settings.repeats):
        t0 = time.perf_counter()
        for i in range(calls):
            jac(x + 1e-9 * (r * calls + i + 1), p)
        batches.append(1e3 * (time.perf_counter() - t0) / calls)
    return stats(batches)


def nlp_jacobians(settings: Settings, golden: GoldenPlan) -> dict[str, Any]:
    """One evaluation of each NLP's constraint Jacobian, at the golden table's plan of its seed point (scenario II):
    what an IPOPT iteration pays besides its linear algebra."""
    from planner.phases.approach_solve import decision_vector

    state, params, plan = golden.state, golden.parameters, golden.plan
    planner, app = golden.tq.planner, golden.tq.planner.approach
    x_app = np.concatenate([decision_vector(params.approach), np.zeros(app.n_extra)])
    p_app = app.parameter_layout.pack({"attitude_wxyz": state.attitude_wxyz,
                                       "omega_body_rad_s": state.omega_body_rad_s})
    stab = planner.stabilization_problem
    x_stab = np.concatenate([params.stabilization_params, np.zeros(stab.n_extra)])
    return {"approach_jacobian_ms": _jacobian_ms(app.solver, x_app, p_app, settings),
            "stabilization_jacobian_ms": _jacobian_ms(stab.solver, x_stab, stab.parameters(plan.grasp), settings),
            "nlp_jacobian_shapes": {"approach": [len(app.lbg), int(x_app.size)],
                                    "stabilization": [len(stab.lbg), int(x_stab.size)]}}


def primitives(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    golden = golden_plan()
    return {**kinematics(settings), **collision_sweep(settings), **verify_one_plan(settings, golden),
            **nlp_jacobians(settings, golden)}
