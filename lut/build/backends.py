"""The parallel backends of a build: joblib's loky on this machine, or dask on a distributed cluster."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from lut.build.options import BuildOptions
from lut.solve.parent_watch import exit_with_parent
from planner.errors import LutgenError

if TYPE_CHECKING:
    from distributed import Client
    from joblib import Parallel


def parallel_backend(options: BuildOptions) -> tuple[Parallel, Client | None]:
    """A joblib ``Parallel`` for the chosen backend, and the dask client to close after the build (loky: None)."""
    import joblib

    if options.backend == "loky":
        # every worker ends itself when the build dies (loky's own idle timeout would keep it 300 s)
        with joblib.parallel_config(backend="loky", initializer=exit_with_parent, initargs=(os.getpid(),)):
            return joblib.Parallel(n_jobs=options.jobs, return_as="generator_unordered"), None
    if options.backend == "dask":
        try:
            from distributed import Client
        except ImportError:
            raise LutgenError("--backend dask: the 'distributed' package is missing (pip install 'lutgen[dask]')") \
                from None
        try:
            client = Client(options.scheduler, timeout="10s")
        except (OSError, ValueError) as exc:
            raise LutgenError(f"--scheduler {options.scheduler}: cannot connect ({exc})") from None
        # parallel_config resolves joblib's lazily registered external backends ("dask"); Parallel(backend=…)
        # alone does not
        with joblib.parallel_config(backend="dask"):
            return joblib.Parallel(return_as="generator_unordered"), client
    raise LutgenError(f"--backend: must be loky or dask, got {options.backend!r}")
