"""One ``lutgen plan`` or ``lutgen query`` process of the coverage section, as an operator runs it, under a hard
timeout; its record: exit code, wall time (s), the failure reasons named from the plan's verification checks."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from bench_sections.common import ROOT
from bench_sections.envelope import EnvelopeState
from lut.cli.plan_output import SOLVE_NOTE_PREFIX

CLI = ("-c", "from lut.cli.main import main; main()")  # `lutgen` of this checkout, whatever is installed
PHASE = re.compile(r"\((approach|tracking|stabilization)\)")
INFEASIBLE_LINE = re.compile(r"^INFEASIBLE \((?P<elapsed>[^)]*)\): (?P<reason>[^:]+)(?::|$)")
OVER_BUDGET = "over budget"
BUDGET_RAN_OUT = "budget ran out"  # the plan's own deadline ended a solve: on time, but not solved to the end
LATE_START = "late start"  # the plan's approach was to start before its answer came (lut.cli.answer_time)


@dataclass(frozen=True)
class CliRun:
    """What one process did: exit code (None: killed at the hard timeout), wall time (s), its output, and the
    plan file's ``metrics`` (and whole ``document``) when it wrote one."""

    exit_code: int | None
    wall_s: float
    stdout: str
    stderr: str
    metrics: dict[str, Any] | None
    document: dict[str, Any] | None = None


@lru_cache(maxsize=1)
def plan_takes_budget() -> bool:
    """Whether ``lutgen plan`` has ``--budget-s`` (issue 20); without it the hard timeout alone bounds a plan."""
    proc = subprocess.run([sys.executable, *CLI, "plan", "--help"], cwd=ROOT, capture_output=True, text=True)
    return "--budget-s" in proc.stdout


def state_args(state: EnvelopeState) -> list[str]:
    """``--attitude W,X,Y,Z --omega-deg-s X,Y,Z`` to 12 significant digits (what the record reproduces)."""
    return ["--attitude", ",".join(f"{v:.12g}" for v in state.attitude_wxyz),
            "--omega-deg-s", ",".join(f"{v:.12g}" for v in state.omega_body_deg_s)]


def reproduction(args: list[str]) -> str:
    """The one command line that re-runs ``args`` by hand, on one core, keeping the plan."""
    return "OMP_NUM_THREADS=1 lutgen " + shlex.join([*args, "--out", "plan.json"])


def run_cli(args: list[str], kill_after_s: float) -> CliRun:
    """``lutgen ARGS --out PLAN.json`` on one core; killed (its whole process group) after ``kill_after_s``."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(prefix="lutgen-coverage-") as tmp:
        plan_json = Path(tmp) / "plan.json"
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, *CLI, *args, "--out", str(plan_json)], cwd=ROOT, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        try:
            stdout, stderr = proc.communicate(timeout=kill_after_s)
            code: int | None = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # the process group this call started, and nothing else
            stdout, stderr = proc.communicate()
            code = None
        wall = time.perf_counter() - t0
        doc = json.loads(plan_json.read_text(encoding="utf-8")) if plan_json.is_file() else None
    return CliRun(code, wall, stdout, stderr, None if doc is None else doc["metrics"], doc)


def failed_checks(metrics: dict[str, Any]) -> list[dict[str, Any]]:
    """The plan's failing verification checks: name, the phase of the worst sample, value, limit, margin (SI)."""
    out = []
    for name, check in metrics["checks"].items():
        if check["passed"]:
            continue
        where = check["where"] or ""
        phase = PHASE.search(where)
        out.append({"reason": name, "phase": phase.group(1) if phase else "grasp" if "t_grasp" in where else None,
                    "value": check["value"],
                    "limit": check["limit"], "margin": check["margin"], "where": check["where"]})
    return out


EXIT_MEANINGS = {1: "bad input", 2: "infeasible", 64: "usage", 70: "internal error"}  # lut.cli.exit_codes


def failure_reasons(run: CliRun, budget_s: float) -> list[dict[str, Any]]:
    """Why a run did not give a verified plan on time (empty: it did): failing checks, or the one-line reason
    of a plan refused before solving, or ``over budget``, or a bad input / crash (a bug here)."""
    if run.exit_code is None:  # a plan written before the kill still says what failed
        failed = [] if run.metrics is None else failed_checks(run.metrics)
        return [{"reason": OVER_BUDGET, "detail": f"killed after {run.wall_s:.1f} s (budget {budget_s:g} s)"},
                *failed]
    late = [{"reason": OVER_BUDGET, "detail": f"{run.wall_s:.1f} s (budget {budget_s:g} s)"}] \
        if run.wall_s > budget_s else []
    if run.exit_code == 0:
        return late
    if run.exit_code == 2 and run.metrics is not None:
        late_start = late_start_reason(run.document or {})
        checks = failed_checks(run.metrics) or ([] if late_start else [{"reason": "infeasible",
                                                                         "detail": last_line(run.stderr)}])
        return budget_ran_out(run.metrics) + checks + late_start + late
    for line in run.stderr.splitlines():
        match = INFEASIBLE_LINE.match(line.strip())
        if run.exit_code == 2 and match:  # refused before solving (out of reach), no plan written
            return [{"reason": match["reason"].strip(), "detail": line.strip()}, *late]
    what = EXIT_MEANINGS.get(run.exit_code, f"exit {run.exit_code}")
    return [{"reason": what, "detail": last_line(run.stderr) or "(nothing on stderr)"}, *late]


def late_start_reason(document: dict[str, Any]) -> list[dict[str, Any]]:
    """``[{"reason": "late start", …}]`` when the plan file's ``answer`` says its approach was to start before the
    answer came, else ``[]``."""
    answer = document.get("answer") or {}
    if not answer.get("late"):
        return []
    return [{"reason": LATE_START, "detail": f"the approach at {answer['start_delay_s']:.2f} s, the answer at "
                                             f"{answer['answered_s']:.1f} s after the observation"}]


def budget_ran_out(metrics: dict[str, Any]) -> list[dict[str, Any]]:
    """``[{"reason": "budget ran out", …}]`` when the plan's deadline ended a solve (its notes or a solver status
    say so), else ``[]``: the failing checks of such a plan are where the solve stood, not what it could reach."""
    cut = [note for note in metrics.get("notes", []) if "time budget ran out" in note]
    statuses = [f"{phase} {solve['status']}" for phase, solve in metrics.get("solver", {}).items()
                if isinstance(solve, dict) and solve.get("status") == "Out_Of_Time"]
    return [{"reason": BUDGET_RAN_OUT, "detail": "; ".join(cut + statuses)}] if cut or statuses else []


def last_line(text: str) -> str:
    """The last non-empty line of ``text`` ('' if none)."""
    lines = [line for line in text.splitlines() if line.strip()]
    return lines[-1].strip() if lines else ""


def query_latency_s(source_line: str) -> dict[str, float]:
    """A query's ``source …`` line as ``{stage: seconds}``: the table load and each ``name V ms`` stage."""
    load = re.search(r"table load ([\d.]+) s", source_line)
    out = {} if load is None else {"table_load": float(load.group(1))}
    out.update({m.group(1): float(m.group(2)) / 1e3 for m in re.finditer(r"(\w+) ([\d.]+) ms", source_line)})
    return out


def run_record(args: list[str], run: CliRun, budget_s: float) -> dict[str, Any]:
    """Everything needed to judge and reproduce one run; the plan's verification and solver record in brief."""
    reasons = failure_reasons(run, budget_s)
    m = run.metrics or {}
    # a query prints its own notes and its solve's (which its plan file keeps too), a plan its plan's: each once
    printed = [line.removeprefix(SOLVE_NOTE_PREFIX).removeprefix("note: ") for line in run.stdout.splitlines()
               if line.startswith("note: ")]
    notes = list(dict.fromkeys([*printed, *m.get("notes", [])]))
    source = [line.split()[1] for line in run.stdout.splitlines() if line.startswith("source ")]
    latency = [query_latency_s(line) for line in run.stdout.splitlines() if line.startswith("source ")]
    refine = [line.split(": ", 1)[1] for line in run.stderr.splitlines() if line.startswith("refine did not finish: ")]
    return {"command": reproduction(args), "exit_code": run.exit_code, "wall_s": run.wall_s,
            "feasible_on_time": not reasons, "reasons": reasons, "notes": notes,
            "source": source[0] if source else None, "violations": m.get("violations"),
            "solver": m.get("solver"), "start_delay_s": m.get("start_delay_s"),
            "free_axis_angle_deg": m.get("free_axis_angle_deg"), "refine_failure": refine[0] if refine else None,
            "latency_s": latency[0] if latency else None,
            "last_line": last_line(run.stderr)}
