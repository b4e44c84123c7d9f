"""``baseline``: the scenario II approach NLP solved by IPOPT (exact CasADi derivatives) and by
``scipy.optimize.minimize(method="SLSQP")`` with finite-difference gradients (the paper's kind of
solver), from the same start, with the same bounds and tolerance number, on the same CasADi functions.

Two problems: the feasibility NLP the bundled scenarios solve, and the paper's approach costs
(manipulability + minimum distance, weight 1 each), where exact derivatives should pay most. A time ratio
is reported only when both solvers converged (solver success and every constraint within the tolerance);
otherwise the section says why there is none."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import OptimizeResult, minimize

from bench_sections.common import Settings, load_scenario_named, timed

if TYPE_CHECKING:
    from planner.config.settings import CostWeights


class ApproachNLP:
    """The approach NLP as plain numpy functions of the decision vector ``w``, with the bounds and the
    start point exactly as ``ApproachProblem._solve_once`` assembles them (tracking-rate scale 1)."""

    def __init__(self, settings: Settings, costs: CostWeights | None = None) -> None:
        from planner.phases.approach import ApproachProblem
        from planner.phases.approach_guess import initial_guesses

        sc = load_scenario_named("scenario_II")
        if costs is not None:
            sc = replace(sc, costs=costs)
        if settings.baseline_max_delay_s is not None:
            sc = replace(sc, phases=replace(sc.phases, max_start_delay_s=settings.baseline_max_delay_s))
        self.scenario = sc
        self.problem, self.build_s = timed(lambda: ApproachProblem(sc))
        prob = self.problem
        state = sc.target_state.as_state()
        # the planner's own cold start: the best scanned initial guess
        guess, self.guess_s = timed(lambda: initial_guesses(sc, prob.spline, state, 1)[0])
        w0 = np.concatenate([guess.params, guess.base_offset_m, [guess.start_delay_s], guess.q_tracking.ravel()])
        self.w0 = np.concatenate([np.clip(w0, prob.lbw[:prob.n_w], prob.ubw[:prob.n_w]), np.zeros(prob.n_extra)])
        self.p = np.concatenate([state.attitude_wxyz, state.omega_body_rad_s])
        self.lbx, self.ubx, self.lbg, self.ubg = prob.lbw, prob.ubw, prob.lbg, prob.ubg
        self._f = prob.solver.get_function("nlp_f")
        self._g = prob.solver.get_function("nlp_g")
        self._g_cache: dict[bytes, np.ndarray] = {}
        self.g_evaluations = 0

    def f(self, w: np.ndarray) -> float:
        return float(self._f(w, self.p))

    def g(self, w: np.ndarray) -> np.ndarray:
        # scipy differences the equality and the inequality constraints separately, at the same points:
        # remembering the last few points keeps SLSQP at one CasADi evaluation per point, as a fair SQP
        key = np.asarray(w, dtype=float).tobytes()
        if key not in self._g_cache:
            if len(self._g_cache) > 2 * self.w0.size + 8:
                del self._g_cache[next(iter(self._g_cache))]  # the oldest (dicts keep insertion order)
            self._g_cache[key] = np.asarray(self._g(w, self.p)).ravel()
            self.g_evaluations += 1
        return self._g_cache[key]

    def max_violation(self, w: np.ndarray) -> float:
        """Largest violation of any constraint or variable bound (their own units: m, rad, rad/s)."""
        gw = self.g(w)
        return float(max(np.max(np.maximum(self.lbg - gw, gw - self.ubg), initial=0.0),
                         np.max(np.maximum(self.lbx - w, w - self.ubx), initial=0.0)))


def solve_ipopt(nlp: ApproachNLP) -> dict[str, Any]:
    """The planner's solver call (``ApproachProblem._solve_once``, a cold start) from ``nlp.w0``."""
    solver = nlp.problem.cold_solver
    # the planner's own arming of the iteration callback: no feasibility stop, no budget
    nlp.problem.budget.arm(nlp.lbg, nlp.ubg, stop_when_feasible=False, max_iterations=None)
    sol, seconds = timed(lambda: solver(x0=nlp.w0, p=nlp.p, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg))
    st = solver.stats()
    w = np.asarray(sol["x"]).ravel()
    return {"time_s": seconds, "objective": float(sol["f"]), "max_violation": nlp.max_violation(w),
            "iterations": int(st["iter_count"]), "success": bool(st["success"]), "status": str(st["return_status"]),
            "g_evaluations": int(st.get("n_call_nlp_g", 0)), "jacobian_evaluations": int(st.get("n_call_nlp_jac_g", 0))}


def _slsqp_constraints(nlp: ApproachNLP) -> list[dict[str, Any]]:
    """Equalities (lbg == ubg) and both finite sides of the other rows, as SLSQP wants them (≥ 0)."""
    lbg, ubg = nlp.lbg, nlp.ubg
    eq = np.isfinite(lbg) & (lbg == ubg)
    lo = np.isfinite(lbg) & ~eq
    hi = np.isfinite(ubg) & ~eq
    return [{"type": "eq", "fun": lambda w: nlp.g(w)[eq] - lbg[eq]},
            {"type": "ineq", "fun": lambda w: np.concatenate([nlp.g(w)[lo] - lbg[lo], ubg[hi] - nlp.g(w)[hi]])}]


def solve_slsqp(nlp: ApproachNLP, cap_s: float, max_iter: int) -> dict[str, Any]:
    """SLSQP from ``nlp.w0``, no derivatives given (scipy differences them), stopped at ``cap_s`` seconds."""
    bounds = [(lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None) for lo, hi in zip(nlp.lbx, nlp.ubx,
                                                                                                     strict=True)]
    t0 = time.perf_counter()

    def wall_cap(intermediate_result: OptimizeResult) -> None:
        if time.perf_counter() - t0 > cap_s:
            raise StopIteration  # scipy ends the solve, returns this iterate, status 99

    nlp.g_evaluations = 0
    res = minimize(nlp.f, nlp.w0, method="SLSQP", bounds=bounds, constraints=_slsqp_constraints(nlp),
                   callback=wall_cap, options={"maxiter": max_iter, "ftol": nlp.scenario.solver.tol})
    seconds = time.perf_counter() - t0
    return {"time_s": seconds, "objective": nlp.f(res.x), "max_violation": nlp.max_violation(res.x),
            "iterations": int(res.nit), "success": bool(res.success), "status": str(res.message),
            "capped": res.status == 99, "cap_s": cap_s, "max_iter": max_iter, "g_evaluations": nlp.g_evaluations,
            "f_evaluations": int(res.nfev)}


def converged(result: dict[str, Any], tol: float) -> bool:
    """Solver success, not capped, and every constraint and bound within ``tol`` (m, rad, rad/s)."""
    return result["success"] and not result.get("capped", False) and result["max_violation"] <= tol


def compare(nlp: ApproachNLP, settings: Settings) -> dict[str, Any]:
    """Both solvers on one problem from one start; the time ratio only between converged solves."""
    ipopt = solve_ipopt(nlp)
    slsqp = solve_slsqp(nlp, settings.baseline_cap_s, settings.baseline_max_iter)
    tol = nlp.scenario.solver.tol
    failed = [name for name, r in (("IPOPT", ipopt), ("SLSQP", slsqp)) if not converged(r, tol)]
    comparison: dict[str, Any] = {"time_ratio_slsqp_over_ipopt": None, "not_comparable": ""}
    if failed:
        comparison["not_comparable"] = f"{' and '.join(failed)} did not converge to tol {tol:g}: no time ratio"
    else:
        comparison["time_ratio_slsqp_over_ipopt"] = slsqp["time_s"] / ipopt["time_s"]
    problem = {"scenario": "scenario_II", "variables": int(nlp.w0.size), "constraints": int(nlp.lbg.size),
               "max_start_delay_s": nlp.scenario.phases.max_start_delay_s, "tol": tol, "build_s": nlp.build_s,
               "initial_guess_s": nlp.guess_s}
    return {"problem": problem, "ipopt_exact": ipopt, "slsqp_finite_difference": slsqp, **comparison}


def paper_costs(scenario_costs: CostWeights) -> CostWeights:
    """The paper's approach costs (Eq. 14-15): manipulability and minimum distance, weight 1 each."""
    return replace(scenario_costs, manipulability=1.0, min_distance=1.0)


def baseline(settings: Settings) -> dict[str, Any]:
    """The whole section: the feasibility NLP, then (not with ``--trim``) the paper's approach costs."""
    result = compare(ApproachNLP(settings), settings)
    if settings.trim:
        result["paper_costs"] = {"skipped": "--trim"}
    else:
        costs = paper_costs(load_scenario_named("scenario_II").costs)
        result["paper_costs"] = compare(ApproachNLP(settings, costs), settings)
    result["notes"] = ("same start (the planner's best scanned guess), bounds and CasADi nlp_f/nlp_g; tol is IPOPT's "
                       "tol and SLSQP's ftol; a time ratio only between solves that both converged")
    return result
