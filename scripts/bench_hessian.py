"""Measure IPOPT variants (Hessian treatment, limited-memory options) on seeded test beds (issues 19-21).

    PYTHONPATH=. .venv/bin/python scripts/bench_hessian.py plan --bed a --variant lbfgs [--save DIR]
    PYTHONPATH=. .venv/bin/python scripts/bench_hessian.py stab --beds a,b --variants lbfgs,exact --load DIR
    PYTHONPATH=. .venv/bin/python scripts/bench_hessian.py check

``plan`` makes one whole plan of a bed under a variant (every NLP), verifies it, prints the approach and
stabilization iterations, seconds, the verdict and the cost, and (``--save``) pickles every stabilization
solve the plan asked for (grasp state, warm start, budgets). ``stab`` re-solves those recorded stabilization
calls under each variant, alternating variants per call so the machine's load hits all alike. ``check``
compares the exact-Hessian variant's Hessian with the chain rule on a small case.

Beds: ``a`` scenario II default state (cold); ``b`` the golden CI table's in-cell query state, its warm
refine; ``c1``/``c2`` scenario I / II default state with the paper's approach costs (manipulability +
min_distance); ``d0``…``d8`` the seeded envelope states of ``scripts/make_truth_plans.py`` (by index).
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]

# variant name -> (IPOPT options over the project's, exact Hessian with zero distance curvature)
VARIANTS: dict[str, tuple[dict, bool]] = {
    "lbfgs": ({}, False),
    "exact": ({"ipopt.hessian_approximation": "exact"}, True),
    "exact_adaptive": ({"ipopt.hessian_approximation": "exact", "ipopt.mu_strategy": "adaptive"}, True),
    "lbfgs_h20": ({"ipopt.limited_memory_max_history": 20}, False),
    "lbfgs_sr1": ({"ipopt.limited_memory_update_type": "sr1"}, False),
    # IPOPT 3.14 already runs adaptive mu under a limited-memory Hessian (its quasi-Newton default): same iterates
    "lbfgs_adaptive": ({"ipopt.mu_strategy": "adaptive"}, False),
    "lbfgs_monotone": ({"ipopt.mu_strategy": "monotone"}, False),
    "lbfgs_monotone_mu3": ({"ipopt.mu_strategy": "monotone", "ipopt.mu_init": 1e-3}, False),
    "lbfgs_noscale": ({"ipopt.nlp_scaling_method": "none"}, False),
    "lbfgs_push": ({"ipopt.bound_push": 1e-8, "ipopt.bound_frac": 1e-8}, False),
    "lbfgs_resto": ({"ipopt.start_with_resto": "yes"}, False),
    "lbfgs_mu4": ({"ipopt.mu_init": 1e-4}, False),  # ignored by the adaptive strategy: same iterates
    "lbfgs_h20_noscale": ({"ipopt.limited_memory_max_history": 20, "ipopt.nlp_scaling_method": "none"}, False),
}


def _zero_curvature_callback() -> None:
    """The distance callback's Jacobian gets a Jacobian of its own, identically zero (Gauss-Newton distances)."""
    from planner.collision import callback as cb

    def get_jacobian(self: ca.Callback, name: str, inames: list, onames: list, opts: dict) -> ca.Function:
        sp = [self.sparsity_in(i) for i in range(self.n_in())] + [self.sparsity_out(j) for j in range(self.n_out())]
        ins = [ca.MX.sym(n, s) for n, s in zip(inames, sp, strict=True)]
        outs = [ca.MX(ca.Sparsity(self.numel_out(0), self.numel_in(i))) for i in range(self.n_in())]
        return ca.Function(name, ins, outs, inames, onames, opts)

    cb._DistanceJacobian.has_jacobian = lambda self: True
    cb._DistanceJacobian.get_jacobian = get_jacobian


def _second_derivatives_compiled(exact: bool) -> None:
    """Exact Hessians run on the interpreted SX Functions: the C of a compiled Jacobian's Jacobian is too large to
    compile (the RK4 step's: 178 MB of C)."""
    import os

    os.environ["LUTGEN_COMPILE"] = "0" if exact else "1"


def apply_variant(name: str) -> None:
    """Patch the NLP modules' IPOPT options (before any problem is built) for ``name``."""
    import planner.phases.approach as ap
    import planner.phases.stabilization as st
    from planner.nlp import ipopt

    extra, exact = VARIANTS[name]
    base = ipopt.ipopt_options
    for module in (ap, st):
        module.ipopt_options = lambda s, *a, _b=base: _b(s, *a) | extra
    if exact:
        _zero_curvature_callback()
    _second_derivatives_compiled(exact)


def bed_state(bed: str) -> tuple[Any, Any, None]:
    """``(scenario, state, warm parameters or None, costs)`` of a bed."""
    from lut.cli.options import cost_weights
    from planner.config.scenario import load_scenario
    from planner.model.target import TargetState

    scen = {"I": "configs/scenarios/scenario_I.toml", "II": "configs/scenarios/scenario_II.toml"}
    if bed in ("a", "c1", "c2"):
        sc = load_scenario(ROOT / scen["I" if bed == "c1" else "II"])
        if bed != "a":
            sc = replace(sc, costs=cost_weights(sc.costs, ("manipulability", "min_distance")))
        ts = sc.target_state
        return sc, TargetState(np.asarray(ts.attitude_wxyz), np.asarray(ts.omega_body_rad_s)), None
    if bed == "b":
        return None, TargetState(np.array([0.991444861, 0, 0, 0.130526192]), np.radians([0.0, 0.0, 3.9])), None
    sys.path.insert(0, str(ROOT / "scripts"))
    from make_truth_plans import SEED, cases

    case = cases(np.random.default_rng(SEED), ROOT / "tests/data/ci_golden.h5")[int(bed[1:])]
    sc = load_scenario(ROOT / case["scenario"])
    return sc, TargetState(np.asarray(case["attitude_wxyz"]), np.radians(case["omega_body_deg_s"])), None


def plan_bed(bed: str, variant: str, save: Path | None) -> None:
    """One whole plan of ``bed`` under ``variant``: iterations, seconds, verdict; the stabilization calls kept."""
    apply_variant(variant)
    import planner.grasp_candidate as gc  # every plan's stabilization solves go through GraspCandidate.stabilize
    from planner.deadline import NO_DEADLINE
    from planner.verify.verifier import verify

    calls = []
    solve = gc.solve_stabilization

    def recording(problem: Any, grasp: Any, warm: Any, max_it: Any = None, screen: Any = None,
                  deadline: Any = NO_DEADLINE, stall: Any = None) -> Any:
        out = solve(problem, grasp, warm, max_it, screen, deadline, stall)
        calls.append({"grasp": grasp, "warm": warm, "max_it": max_it, "screen": screen, "stall": stall,
                      "iterations": out.iterations, "status": str(out.status), "solve_s": out.solve_time_s})
        return out

    gc.solve_stabilization = recording
    t0 = time.perf_counter()
    sc, state, _ = bed_state(bed)
    if bed == "b":
        from lut.query.table_query import TableQuery

        tq = TableQuery(ROOT / "tests/data/ci_golden.h5")
        found = tq.interpolate(state)
        built = time.perf_counter()
        result = tq.planner.plan(state, found.parameters)
    else:
        from planner.plan import Planner

        planner = Planner(sc)
        built = time.perf_counter()
        result = planner.plan(state)
    wall = time.perf_counter() - built
    report = verify(result)
    app, stab = result.approach, result.stabilization
    stab_it = sum(c["iterations"] for c in calls)
    stab_s = sum(c["solve_s"] for c in calls)
    print(f"bed {bed} variant {variant}: build {built - t0:.1f} s, plan {wall:.1f} s, "
          f"approach {app.iterations} it {app.solve_time_s:.1f} s cost {app.cost:.6g}, "
          f"stabilization {stab_it} it over {len(calls)} solves {stab_s:.1f} s "
          f"({stab_s / max(stab_it, 1):.3f} s/it) last {stab.status} {stab.iterations} it, "
          f"verify {'FEASIBLE' if report.feasible else 'INFEASIBLE ' + '; '.join(report.violations)[:200]}",
          flush=True)
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        with open(save / f"stab_{bed}.pkl", "wb") as fh:
            pickle.dump({"scenario": sc if bed != "b" else tq.planner.scenario, "calls": calls}, fh)


def stab_beds(beds: list[str], variants: list[str], load: Path) -> None:
    """Re-solve the recorded stabilization calls of ``beds`` under every variant, alternating per call."""
    import planner.phases.stabilization as st
    from planner.phases.stabilization_solve import solve_stabilization

    if any(VARIANTS[v][1] for v in variants):
        _zero_curvature_callback()
    base = st.ipopt_options
    problems: dict[tuple[str, str], st.StabilizationProblem] = {}
    for bed in beds:
        with open(load / f"stab_{bed}.pkl", "rb") as fh:
            rec = pickle.load(fh)
        for i, call in enumerate(rec["calls"]):
            for variant in variants:
                key = (rec["scenario"].name + str(rec["scenario"].costs), variant)
                if key not in problems:
                    st.ipopt_options = lambda s, *a, _e=VARIANTS[variant][0]: base(s, *a) | _e
                    _second_derivatives_compiled(VARIANTS[variant][1])
                    t = time.perf_counter()
                    problems[key] = st.StabilizationProblem(rec["scenario"])
                    print(f"  built {variant} in {time.perf_counter() - t:.1f} s", flush=True)
                t = time.perf_counter()
                st.ipopt_options = lambda s, *a, _e=VARIANTS[variant][0]: base(s, *a) | _e
                _second_derivatives_compiled(VARIANTS[variant][1])
                out = solve_stabilization(problems[key], call["grasp"], call["warm"], call["max_it"], call["screen"],
                                          stall=call.get("stall"))
                wall = time.perf_counter() - t
                print(f"bed {bed} call {i} ({'warm' if call['warm'] is not None else 'cold'}, budget {call['max_it']},"
                      f" screen {call['screen']}) {variant:15s}: {out.iterations:4d} it {wall:7.2f} s "
                      f"({wall / max(out.iterations, 1):.3f} s/it) {out.status} torque {out.peak_torque_nm:.3f} "
                      f"dist {out.min_distance_m:.4f} cost {out.cost:.4g}  [recorded {call['iterations']} it "
                      f"{call['status']}]", flush=True)


def check_hessian() -> None:
    """The exact-Hessian variant's Lagrangian Hessian on a small case against the chain rule with zero distance
    curvature: ``Σ λ_i ∇d_i(pose)·∂²pose/∂x²``, the pose's second derivative by central differences."""
    _zero_curvature_callback()
    from planner.collision.callback import SceneDistanceCallback, pose_vector
    from planner.collision.layout import TARGET_BODY
    from planner.collision.nlp_scene import build_scene
    from planner.config.scenario import load_scenario

    sc = load_scenario(ROOT / "configs/scenarios/scenario_II.toml")
    frames = [*sc.robot.body_names, TARGET_BODY]
    cb = SceneDistanceCallback("d", build_scene(sc), frames, 1)
    x = ca.MX.sym("x", 3)
    rng = np.random.default_rng(0)
    blocks = []
    for i in range(len(frames)):
        a, c, s = rng.normal(size=3), ca.cos(x[0] * rng.normal()), ca.sin(x[0] * rng.normal())
        R = ca.mtimes(ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1)),
                      ca.DM(np.linalg.qr(rng.normal(size=(3, 3)))[0]))
        p = ca.vertcat(2 * np.sin(i) + a[0] * x[1] ** 2, 2 * np.cos(i) + a[1] * x[2] * x[0],
                       0.3 * i + a[2] * x[1] * x[2])
        blocks.append(pose_vector(R, p))
    pose = ca.vertcat(*blocks)
    lam = rng.normal(size=cb.n_out)
    x0 = np.array([0.3, -0.2, 0.5])
    hessian = np.array(ca.Function("H", [x], [ca.hessian(ca.dot(ca.DM(lam), cb(pose)), x)[0]])(x0))
    pose_jacobian = ca.Function("Jp", [x], [ca.jacobian(pose, x)])
    gradient = lam @ cb.evaluate(np.array(ca.Function("P", [x], [pose])(x0)).ravel(), with_jacobian=True)[1]
    h = 1e-5
    reference = np.stack([gradient @ (np.array(pose_jacobian(x0 + h * e)) - np.array(pose_jacobian(x0 - h * e)))
                          / (2 * h) for e in np.eye(3)], axis=1)
    print(f"Hessian vs chain rule with zero distance curvature: max |diff| {np.abs(hessian - reference).max():.2e} "
          f"(entries up to {np.abs(reference).max():.2f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("plan")
    p.add_argument("--bed", required=True)
    p.add_argument("--variant", default="lbfgs", choices=sorted(VARIANTS))
    p.add_argument("--save", type=Path)
    s = sub.add_parser("stab")
    s.add_argument("--beds", required=True)
    s.add_argument("--variants", default="lbfgs,exact")
    s.add_argument("--load", type=Path, required=True)
    sub.add_parser("check")
    args = ap.parse_args()
    if args.command == "check":
        check_hessian()
    elif args.command == "plan":
        plan_bed(args.bed, args.variant, args.save)
    else:
        stab_beds(args.beds.split(","), args.variants.split(","), args.load)


if __name__ == "__main__":
    main()
