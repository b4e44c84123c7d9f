"""IPOPT through CasADi, set up the one way every phase NLP uses it.

IPOPT's linear solver (MUMPS) runs on the OpenBLAS CasADi ships, which by default starts one thread per
core. Its threaded reductions round differently from the serial ones, and a last-bit difference is
enough to change a solve (feasible against the iteration limit, in collision). Same inputs must give the
same plan (and table), so that library runs with one thread. Nothing is lost: the KKT systems are too small
to gain from threads, and a table build already runs one worker per core.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path
from typing import Any

import casadi as ca

from planner.config.scenario import SolverSettings

CONSTRAINT_TOL = 1e-7  # IPOPT's constr_viol_tol of every phase NLP (rad, rad/s, m, N·m, N)

# the OpenBLAS CasADi's IPOPT plugin links (casadi/libcasadi-tp-openblas.so.0)
_CASADI_OPENBLAS = "libcasadi-tp-openblas.so.0"


@functools.cache
def pin_ipopt_blas_threads() -> None:
    """Set the OpenBLAS under CasADi's IPOPT to one thread (once per process: the library is loaded here).

    Loading the library by its path returns the handle the IPOPT plugin uses (same soname), whether or
    not the plugin is loaded yet, so this holds regardless of import order or environment variables.
    """
    lib = ctypes.CDLL(str(Path(ca.__file__).parent / _CASADI_OPENBLAS))
    lib.openblas_set_num_threads(1)


def ipopt_options(solver: SolverSettings, constr_viol_tol: float = CONSTRAINT_TOL) -> dict[str, Any]:
    """The options every phase NLP shares: limited-memory Hessian, the scenario's iteration and wall-time
    limits and tolerance, ``acceptable_tol`` 1e-4, silent.

    ``max_iter`` is what ends a hopeless solve (deterministic); ``max_wall_s`` is a machine-dependent
    safety net only. ``constr_viol_tol`` is in the constraints' own units (rad, rad/s, m, N·m, N).
    """
    return {
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.max_iter": solver.max_iter,
        "ipopt.max_wall_time": solver.max_wall_s,
        "ipopt.tol": solver.tol,
        "ipopt.acceptable_tol": 1e-4,
        "ipopt.constr_viol_tol": constr_viol_tol,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "print_time": False,
    }


def ipopt_solver(name: str, nlp: dict[str, ca.MX], options: dict[str, Any]) -> ca.Function:
    """``casadi.nlpsol(name, "ipopt", nlp, options)`` with IPOPT's BLAS pinned to one thread."""
    pin_ipopt_blas_threads()
    return ca.nlpsol(name, "ipopt", nlp, options)
