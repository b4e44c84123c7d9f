"""``carry`` (issue 20): how far a plan carries, the measurement a table's resolution follows from.

A table answers a state between its points with a neighbour's plan (interpolated, or a corner's own), re-simulated
and verified at the state; where it fails, the query solves. So a grid spacing is useful only where a plan still
verifies half a spacing away. For each of the coverage section's seeded states (``--coverage-states``; the kinds of
``--coverage-kinds``, default the two general tumbles) a cold plan is made in process under the coverage budget;
each feasible plan is then re-simulated at states displaced from its own by an attitude rotation of δθ about a
seeded random axis (body frame, composed on the right), or by a body-rate change of δω along that axis, and verified
densely: *as is*, and *repaired* as the query repairs a plan that fails only from its grasp on (its stabilization
re-solved warm at the grasp it reaches). Per kind and displacement: the fraction of plans that still verify, and
the failing checks tallied.
"""

from __future__ import annotations

import sys
from collections import Counter
from typing import Any

import numpy as np

from bench_sections.common import Settings, load_scenario_named
from bench_sections.coverage import KINDS, kind_states

SEED_SALT = 2020  # the displacement directions' seed is (--seed, this, kind)
ATTITUDE_STEPS_DEG = (2.5, 5.0, 10.0, 20.0, 45.0)
RATE_STEPS_DEG_S = (0.25, 0.5, 1.0, 2.0)
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


def carried(planner: Any, state: Any, parameters: Any) -> dict[str, Any]:
    """The plan of ``parameters`` re-simulated and verified at ``state``; repaired as a query repairs it."""
    from lut.query.stabilization_repair import repaired_plan
    from planner.verify.verifier import verify

    plan = planner.simulate(state, parameters)
    report = verify(plan)
    repaired = report.feasible or repaired_plan(planner, plan, report) is not None
    return {"as_is": bool(report.feasible), "repaired": bool(repaired),
            "failed": [c.name for c in report.checks.values() if not c.passed]}


def kind_carry(kind: Any, n: int, seed: int, budget_s: float) -> dict[str, Any]:
    """One kind: ``n`` cold plans (each within ``budget_s`` [s]), each feasible one carried to every displacement."""
    from planner.deadline import Deadline
    from planner.plan import OutOfReach, Planner
    from planner.verify.verifier import verify

    planner = Planner(load_scenario_named(kind.scenario))
    rng = np.random.default_rng([seed, SEED_SALT, KINDS.index(kind)])
    steps = [("attitude_deg", d, d, 0.0) for d in ATTITUDE_STEPS_DEG]
    steps += [("rate_deg_s", d, 0.0, d) for d in RATE_STEPS_DEG_S]
    runs: dict[str, list[dict[str, Any]]] = {f"{name} {d:g}": [] for name, d, _, _ in steps}
    planned = 0
    for i, s in enumerate(kind_states(kind, n, seed)):
        axis = _unit(rng)  # drawn for every state, so the directions do not depend on which plans are feasible
        state = s.target_state()
        try:
            plan = planner.plan(state, deadline=Deadline.after(budget_s))
        except OutOfReach:
            plan = None
        held = []
        if plan is not None and verify(plan).feasible:
            planned += 1
            for name, d, att, rate in steps:
                run = carried(planner, displaced(state, att, rate, axis), plan.parameters)
                runs[f"{name} {d:g}"].append(run)
                held.append(f"{d:g} {'yes' if run['repaired'] else 'no'}")
        print(f"bench: carry {kind.name} state {i + 1}/{n}: "
              f"{'carried (attitude °, rate °/s): ' + ', '.join(held) if held else 'no feasible plan'}",
              file=sys.stderr, flush=True)
    return {"states": n, "feasible_plans": planned, "steps": {key: _digest(r) for key, r in runs.items()}}


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
                           "attitude_steps_deg": list(ATTITUDE_STEPS_DEG), "rate_steps_deg_s": list(RATE_STEPS_DEG_S)}
    for kind in KINDS:
        if kind.name not in names:
            continue
        entry = kind_carry(kind, c.states, settings.seed, c.budget_s)
        entry["largest_attitude_deg"] = largest_carry(entry, "attitude_deg")
        entry["largest_rate_deg_s"] = largest_carry(entry, "rate_deg_s")
        out[kind.name] = entry
    return out
