"""``baseline``: the scenario II approach NLP solved by IPOPT (exact CasADi derivatives) and by
``scipy.optimize.minimize(method="SLSQP")`` with finite-difference gradients (the paper's kind of
solver), from the same start, with the same bounds and tolerance number, on the same CasADi functions."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult, minimize

from bench_sections.common import Settings, load_scenario_named, timed


class ApproachNLP:
    """The approach NLP as plain numpy functions of the decision vector ``w``, with the bounds and the
    start point exactly as ``ApproachProblem._solve_once`` assembles them (tracking-rate scale 1)."""

    def __init__(self, settings: Settings) -> None:
        from planner.phases.approach import ApproachProblem
        from planner.phases.approach_guess import initial_guesses

        sc = load_scenario_named("scenario_II")
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


def baseline(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    nlp = ApproachNLP(settings)
    ipopt = solve_ipopt(nlp)
    slsqp = solve_slsqp(nlp, settings.baseline_cap_s, settings.baseline_max_iter)
    return {"problem": {"scenario": "scenario_II", "variables": int(nlp.w0.size), "constraints": int(nlp.lbg.size),
                        "max_start_delay_s": nlp.scenario.phases.max_start_delay_s, "tol": nlp.scenario.solver.tol,
                        "build_s": nlp.build_s, "initial_guess_s": nlp.guess_s},
            "ipopt_exact": ipopt, "slsqp_finite_difference": slsqp,
            "time_ratio_slsqp_over_ipopt": slsqp["time_s"] / ipopt["time_s"],
            "notes": "same start (the planner's best scanned guess), bounds and CasADi nlp_f/nlp_g; tol is IPOPT's "
                     "tol and SLSQP's ftol; a capped or iteration-limited SLSQP makes the ratio a lower bound"}
