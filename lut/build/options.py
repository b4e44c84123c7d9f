"""What a build is asked to do (``lutgen build``'s options) and what it reports back."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from lut.build.polish import PolishOutcome
from lut.solve.point_process import DEFAULT_SOLVER
from planner.errors import LutgenError

MAX_POINT_TIMEOUT_S = 7 * 86400.0  # a longer per-point limit is surely a typo [s]
BACKENDS = ("loky", "dask")


@dataclass
class BuildOptions:
    """``lutgen build``'s options (docs/table.md, Build)."""

    jobs: int = 1
    backend: str = "loky"  # or "dask"
    scheduler: str | None = None  # dask: tcp://HOST:PORT
    point_timeout_s: float = 900.0  # [s]
    resume: bool = False  # continue the journal; a complete table is left as it is
    force: bool = False  # start over: an existing table (replaced when the new one is complete) or journal
    solver: str = DEFAULT_SOLVER  # module:function run in the point process
    progress: bool = True
    robust_sigmas: tuple[float, float] | None = None  # --robust: 1-σ attitude [deg] and body rate [deg/s]
    robust_samples: int = 20  # drawn states per feasible point with --robust
    cold: bool = False  # --cold: every point planned cold, none warm-started from a neighbour
    reuse: tuple[str, ...] = ()  # --reuse: tables whose feasible plans at this grid's points are taken (the cheapest)
    polish: bool = False  # --polish: points dearer than a neighbour solved again warm from it (lut.build.polish)
    polish_tries: int = 2  # --polish-tries: the cheaper neighbours tried per point, cheapest first
    polish_cold: bool = False  # --polish-cold: then a cold plan, where no neighbour gave a cheaper one

    def solver_kwargs(self) -> dict[str, float]:
        """The point solver's robustness arguments (none without ``--robust``)."""
        if self.robust_sigmas is None:
            return {}
        return {"robust_attitude_sigma_deg": self.robust_sigmas[0], "robust_rate_sigma_deg_s": self.robust_sigmas[1],
                "robust_samples": self.robust_samples}


class BuildOutcome(Enum):
    BUILT = "built"  # points were solved (or all were journaled) and the table written
    ALREADY_COMPLETE = "already complete"  # --resume of a complete table: nothing solved, nothing written


@dataclass
class BuildSummary:
    """What a build did: the table, its point counts by status name, the points solved in this run."""

    table: Path
    n_points: int
    counts: dict[str, int]
    solved_now: int
    wall_time_s: float  # [s]
    failures: list[str] = field(default_factory=list)  # "point N: reason"
    outcome: BuildOutcome = BuildOutcome.BUILT
    reused_now: int = 0  # points taken from --reuse's table in this run
    polish: PolishOutcome = field(default_factory=PolishOutcome)  # what --polish did in this run


def check_options(options: BuildOptions) -> None:
    """Raise :class:`LutgenError` for an option value no build can use (before any file is touched)."""
    if options.resume and options.force:
        raise LutgenError("--resume and --force exclude each other: continue the journal, or start over")
    if not (np.isfinite(options.point_timeout_s) and 0 < options.point_timeout_s <= MAX_POINT_TIMEOUT_S):
        raise LutgenError(f"--point-timeout: must be in (0, {MAX_POINT_TIMEOUT_S:g}] s, got {options.point_timeout_s}")
    least_tries = 0 if options.polish_cold else 1  # no neighbour to try leaves only --polish-cold's cold plan
    if options.polish_tries < least_tries:
        raise LutgenError(f"--polish-tries: must be >= {least_tries} (0 only with --polish-cold), "
                          f"got {options.polish_tries}")
    if options.jobs < 1:
        raise LutgenError(f"-j/--jobs: must be >= 1, got {options.jobs}")
    if options.robust_sigmas is not None and not (all(np.isfinite(v) and v >= 0 for v in options.robust_sigmas)
                                                  and options.robust_samples >= 1):
        raise LutgenError(f"--robust: σ's must be finite numbers >= 0 and --robust-samples >= 1, got "
                          f"{options.robust_sigmas}, {options.robust_samples}")
    if options.backend not in BACKENDS:
        raise LutgenError(f"--backend: must be loky or dask, got {options.backend!r}")
    if options.backend == "dask" and not options.scheduler:
        raise LutgenError("--backend dask needs --scheduler tcp://HOST:PORT")
