"""``carry`` (issue 20): how far a plan carries, the measurement a table's resolution follows from.

A table answers a state between its points with a neighbour's plan (interpolated, or a corner's own), re-simulated
and verified at the state; where it fails, the query solves. So a grid spacing is useful only where a plan still
verifies half a spacing away. For each of the coverage section's seeded states (``--coverage-states``; the kinds of
``--coverage-kinds``, default the two general tumbles) a cold plan is made in process under the coverage budget;
each feasible plan is then re-simulated at displaced states and verified densely: *as is*, and *repaired* as the
query repairs a plan that fails only from its grasp on (its stabilization re-solved warm at the grasp it reaches).
A tumble's plan is displaced by an attitude rotation of δθ about a seeded random axis (body frame, composed on the
right), or by a body-rate change of δω along that axis; a flat spin's along its family, as a flat-spin table
carries it: its spin axis turned by δα in the orbital x–z plane (the phase kept; the plan unchanged), or its spin
rate moved by δr (the plan's start moved so that it meets the target at the same spin angle,
:func:`lut.table.symmetry.start_delay_shift_s`). Per kind and displacement: the fraction of plans that still
verify, and the failing checks tallied.
"""

from __future__ import annotations

import sys
from collections import Counter
from typing import Any

import numpy as np

from bench_sections.common import Settings, load_scenario_named
from bench_sections.coverage import KINDS, kind_states
from bench_sections.envelope import FLAT_SPIN_RATE_DEG_S

SEED_SALT = 2020  # the displacement directions' seed is (--seed, this, kind)
ATTITUDE_STEPS_DEG = (2.5, 5.0, 10.0, 20.0, 45.0)
RATE_STEPS_DEG_S = (0.25, 0.5, 1.0, 2.0)
# a flat spin's: its spin axis in the orbital x–z plane [deg] and its spin rate [deg/s] (the flat-spin carry limits of
# lut.query.carry are 30° and 0.5 °/s outside a grid)
SPIN_AXIS_STEPS_DEG = (5.0, 10.0, 20.0, 30.0, 45.0)
SPIN_RATE_STEPS_DEG_S = (0.125, 0.25, 0.5, 1.0)
DEFAULT_KINDS = ("scenario_I_tumble", "scenario_II_tumble")
CARRY_BAR = 0.9  # a spacing is useful where at least this fraction of plans still verify half a spacing away


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def displaced(state: Any, attitude_deg: float, rate_deg_s: float, axis: np.ndarray) -> Any:
    """``state`` rotated by ``attitude_deg`` about the body ``axis`` (on the right), its body rate moved by
    ``rate_deg_s`` along ``axis``."""
    from scipy.spatial.transform import Rotation

    from planner.model.target_state import TargetState

    w, x, y, z = state.attitude_wxyz
    turned = Rotation.from_quat([x, y, z, w]) * Rotation.from_rotvec(np.radians(attitude_deg) * axis)
    qx, qy, qz, qw = turned.as_quat()
    return TargetState(np.array([qw, qx, qy, qz]), state.omega_body_rad_s + np.radians(rate_deg_s) * axis)


def flat_spin_displaced(state: Any, spin_axis_deg: float, rate_deg_s: float) -> Any:
    """``state`` (a flat spin, |ω| > 0) with its spin axis turned by ``spin_axis_deg`` about the orbital y axis (from
    α to α + ``spin_axis_deg`` in the x–z plane, the phase kept) and its spin rate moved by ``rate_deg_s`` (its axis
    kept)."""
    from scipy.spatial.transform import Rotation

    from planner.model.target_state import TargetState

    w, x, y, z = state.attitude_wxyz
    about_y = Rotation.from_rotvec(np.radians(-spin_axis_deg) * np.array([0.0, 1.0, 0.0]))  # orbital frame: on the left
    turned = about_y * Rotation.from_quat([x, y, z, w])
    qx, qy, qz, qw = turned.as_quat()
    omega = np.asarray(state.omega_body_rad_s, dtype=float)
    rate = float(np.linalg.norm(omega))
    return TargetState(np.array([qw, qx, qy, qz]), omega * (rate + np.radians(rate_deg_s)) / rate)


def carried_to_rate(parameters: Any, scenario: Any, rate_from_deg_s: float, rate_deg_s: float) -> Any:
    """A flat spin's plan made at ``rate_from_deg_s`` carried to ``rate_deg_s`` [deg/s] as a flat-spin table carries it:
    its start moved so that it meets the target at the same spin angle, by whole turns into the start-delay window."""
    from lut.table.symmetry import start_delay_shift_s

    meeting_s = parameters.approach.start_delay_s + scenario.phases.approach_s
    shift_s = start_delay_shift_s(0.0, 0.0, rate_deg_s, rate_from_deg_s=rate_from_deg_s, meeting_s=meeting_s)
    return parameters.shifted_in_time(shift_s, 360.0 / rate_deg_s, scenario.phases.start_delay_window_s)


def carried(planner: Any, state: Any, parameters: Any) -> dict[str, Any]:
    """The plan of ``parameters`` re-simulated and verified at ``state``; repaired as a query repairs it."""
    from lut.query.stabilization_repair import repaired_plan
    from planner.verify.verifier import verify

    plan = planner.simulate(state, parameters)
    report = verify(plan)
    repaired = report.feasible or repaired_plan(planner, plan, report) is not None
    return {"as_is": bool(report.feasible), "repaired": bool(repaired),
            "failed": [c.name for c in report.checks.values() if not c.passed]}


def kind_steps(kind: Any) -> list[tuple[str, float]]:
    """The displacements ``(axis, size)`` a plan of ``kind`` is carried by: a tumble's in attitude [deg] and body
    rate [deg/s]; a flat spin's along its family, spin axis [deg] and spin rate [deg/s]."""
    if kind.motion == "flat_spin":
        return [("spin_axis_deg", d) for d in SPIN_AXIS_STEPS_DEG] + [("rate_deg_s", d) for d in SPIN_RATE_STEPS_DEG_S]
    return [("attitude_deg", d) for d in ATTITUDE_STEPS_DEG] + [("rate_deg_s", d) for d in RATE_STEPS_DEG_S]


def _direction(kind: Any, rng: np.random.Generator) -> Any:
    """A state's seeded direction of displacement: a tumble's body axis (unit), a flat spin's sense of turning its
    spin axis (±1)."""
    return float(rng.choice([-1.0, 1.0])) if kind.motion == "flat_spin" else _unit(rng)


def _displacements(kind: Any, state: Any, parameters: Any, scenario: Any, direction: Any) -> list[tuple[str, Any, Any]]:
    """``(step key, displaced state, the plan's parameters carried there)`` for each of :func:`kind_steps`; a flat
    spin's rate moves towards the middle of the envelope's rates, so that it stays within them."""
    out = []
    rate = float(np.degrees(np.linalg.norm(state.omega_body_rad_s)))
    toward = -1.0 if rate > float(np.mean(FLAT_SPIN_RATE_DEG_S)) else 1.0
    for name, d in kind_steps(kind):
        key = f"{name} {d:g}"
        if kind.motion != "flat_spin":
            turn, moved = (d, 0.0) if name == "attitude_deg" else (0.0, d)
            out.append((key, displaced(state, turn, moved, direction), parameters))
        elif name == "spin_axis_deg":
            out.append((key, flat_spin_displaced(state, direction * d, 0.0), parameters))
        else:
            out.append((key, flat_spin_displaced(state, 0.0, toward * d),
                        carried_to_rate(parameters, scenario, rate, rate + toward * d)))
    return out


def kind_carry(kind: Any, n: int, seed: int, budget_s: float) -> dict[str, Any]:
    """One kind: ``n`` cold plans (each within ``budget_s`` [s]), each feasible one carried to every displacement."""
    from planner.deadline import Deadline
    from planner.plan import OutOfReach, Planner
    from planner.verify.verifier import verify

    scenario = load_scenario_named(kind.scenario)
    planner = Planner(scenario)
    rng = np.random.default_rng([seed, SEED_SALT, KINDS.index(kind)])
    runs: dict[str, list[dict[str, Any]]] = {f"{name} {d:g}": [] for name, d in kind_steps(kind)}
    planned = 0
    for i, s in enumerate(kind_states(kind, n, seed)):
        direction = _direction(kind, rng)  # drawn for every state: the directions do not depend on which plans hold
        state = s.target_state()
        try:
            plan = planner.plan(state, deadline=Deadline.after(budget_s))
        except OutOfReach:
            plan = None
        held = []
        if plan is not None and verify(plan).feasible:
            planned += 1
            for key, moved, parameters in _displacements(kind, state, plan.parameters, scenario, direction):
                run = carried(planner, moved, parameters)
                runs[key].append(run)
                held.append(f"{key} {'yes' if run['repaired'] else 'no'}")
        print(f"bench: carry {kind.name} state {i + 1}/{n}: "
              f"{'carried: ' + ', '.join(held) if held else 'no feasible plan'}", file=sys.stderr, flush=True)
    entry: dict[str, Any] = {"states": n, "feasible_plans": planned,
                             "steps": {key: _digest(r) for key, r in runs.items()}}
    for name in dict.fromkeys(name for name, _ in kind_steps(kind)):
        entry[f"largest_{name}"] = largest_carry(entry, name)
    return entry


def _digest(runs: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(runs)
    return {"plans": n, "as_is": sum(r["as_is"] for r in runs) / n if n else None,
            "repaired": sum(r["repaired"] for r in runs) / n if n else None,
            "failed_checks": dict(Counter(c for r in runs for c in r["failed"]).most_common())}


def largest_carry(entry: dict[str, Any], axis: str) -> float | None:
    """The largest displacement along ``axis`` (``attitude_deg`` or ``rate_deg_s``) at and below which at least
    :data:`CARRY_BAR` of the plans verify, as is or repaired; None when even the smallest does not."""
    best = None
    for key, digest in entry["steps"].items():
        name, size = key.split()
        if name != axis:
            continue
        if digest["repaired"] is None or digest["repaired"] < CARRY_BAR:
            break
        best = float(size)
    return best


def carry(settings: Settings) -> dict[str, Any]:
    """The whole section: per kind, the carry of its feasible plans at each displacement."""
    c = settings.coverage
    names = c.kinds or DEFAULT_KINDS
    out: dict[str, Any] = {"states_per_kind": c.states, "seed": settings.seed, "carry_bar": CARRY_BAR,
                           "attitude_steps_deg": list(ATTITUDE_STEPS_DEG), "rate_steps_deg_s": list(RATE_STEPS_DEG_S),
                           "spin_axis_steps_deg": list(SPIN_AXIS_STEPS_DEG),
                           "spin_rate_steps_deg_s": list(SPIN_RATE_STEPS_DEG_S)}
    for kind in KINDS:
        if kind.name not in names:
            continue
        out[kind.name] = kind_carry(kind, c.states, settings.seed, c.budget_s)
    return out
