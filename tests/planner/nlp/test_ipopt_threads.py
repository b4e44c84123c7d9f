"""IPOPT's BLAS runs one thread, so a plan does not depend on the machine's core count.

Two threads rounded scenario II's approach 4e-15 differently and its stabilization then failed (see
planner.nlp.ipopt); the pin only helps if it reaches the library IPOPT actually calls.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import casadi as ca
import numpy as np

from planner.config.scenario import SolverSettings
from planner.nlp.ipopt import ipopt_options, ipopt_solver


def _loaded_openblas_paths() -> set[str]:
    maps = Path(f"/proc/{os.getpid()}/maps").read_text().splitlines()
    return {line.split()[-1] for line in maps if "openblas" in line.rsplit("/", 1)[-1]}


def test_the_openblas_ipopt_loads_is_the_one_pinned_to_one_thread():
    x = ca.MX.sym("x", 2)
    opts = ipopt_options(SolverSettings(max_iter=50, max_wall_s=10.0, tol=1e-8), constr_viol_tol=1e-8)
    solver = ipopt_solver("threads_probe", {"x": x, "f": ca.sumsqr(x - 1), "g": x[0] + x[1]}, opts)
    sol = solver(x0=[0, 0], lbg=0.0, ubg=0.0)
    assert np.allclose(np.asarray(sol["x"]).ravel(), [0.0, 0.0], atol=1e-7)  # min ‖x−1‖² on x₀+x₁=0
    casadi_dir = Path(ca.__file__).resolve().parent
    ipopt_blas = [p for p in _loaded_openblas_paths() if Path(p).resolve().parent == casadi_dir]
    assert ipopt_blas, "the IPOPT plugin loaded no OpenBLAS from casadi's directory"
    for path in ipopt_blas:  # ask the very library the plugin mapped
        assert ctypes.CDLL(path).openblas_get_num_threads() == 1
