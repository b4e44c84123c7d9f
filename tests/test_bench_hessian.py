"""``scripts/bench_hessian.py`` still measures what it says: a plan's stabilization solves are recorded, and each one
re-solved alone under the project's own IPOPT options ends as the plan's did (same iterations, same outcome).

Slow (two scenario II stabilizations and a plan, ~30 s): run with ``-m slow`` after a change to the planner's
stabilization calls, which the script hooks by name.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "bench_hessian.py"

pytestmark = pytest.mark.slow

# "bed a call 0 (cold, …) lbfgs   :   18 it … Feasible_Point_Found … [recorded 18 it Feasible_Point_Found]"
RESOLVED = re.compile(r"^bed a call \d+ .*?:\s+(\d+) it .*? s/it\) (\S+) .*\[recorded (\d+) it (\S+)\]$")


def _run(*args: str) -> str:
    env = os.environ | {"PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, str(SCRIPT), *args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_recorded_stabilization_solves_are_resolved_as_the_plan_solved_them(tmp_path: Path) -> None:
    planned = _run("plan", "--bed", "a", "--variant", "lbfgs", "--save", str(tmp_path))
    recorded = int(re.search(r"stabilization (\d+) it over (\d+) solves", planned).group(2))
    assert recorded >= 1, planned
    assert (tmp_path / "stab_a.pkl").is_file()
    lines = [m for m in map(RESOLVED.match, _run("stab", "--beds", "a", "--variants", "lbfgs", "--load",
                                                 str(tmp_path)).splitlines()) if m]
    assert len(lines) == recorded
    for m in lines:
        assert (m.group(1), m.group(2)) == (m.group(3), m.group(4))
