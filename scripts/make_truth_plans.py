"""Plan and query seeded target states across the envelope and keep the plans as test data.

    .venv/bin/python scripts/make_truth_plans.py [--out tests/data/truth] [--table tests/data/ci_golden.h5] [-j 2]

The states (seeded): per scenario, flat spins with the spin axis anywhere in the orbital x–z plane (rate
1–4 °/s, any phase) and general tumbles (±4 °/s per body axis, any attitude) through ``lutgen plan``; and
flat spins inside the golden table's grid through ``lutgen query``. Every plan file is thinned to a 0.1 s
step and gzipped; ``index.json`` lists each state, its command and exit code.
``tests/planner/verify/test_truth_plans.py`` re-checks the stored plans' distances with verify's engine,
independently of the plans' own metrics.
"""

from __future__ import annotations

import argparse
import gzip
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from bench_sections.envelope import flat_spin_state, tumble_state

ROOT = Path(__file__).resolve().parents[1]
SEED = 20261201
MAJOR_AXIS = {"scenario_I": 1, "scenario_II": 2}  # body axis of the largest principal moment
PLAN_TIMEOUT_S = 300


def cases(rng: np.random.Generator, table: Path) -> list[dict]:
    """The seeded states: 3 flat spins and 3 tumbles per scenario (plan), 8 in-grid flat spins (query)."""
    out = []
    for scenario, major in MAJOR_AXIS.items():
        for kind in ("flat_spin", "flat_spin", "flat_spin", "tumble", "tumble", "tumble"):
            st = flat_spin_state(rng, np.eye(3)[major], (1.0, 4.0)) if kind == "flat_spin" else tumble_state(rng)
            q, w = st.attitude_wxyz, st.omega_body_deg_s
            out.append({"name": f"plan_{scenario}_{kind}_{len(out)}", "command": "plan", "kind": kind,
                        "scenario": f"configs/scenarios/{scenario}.toml", "attitude_wxyz": q.tolist(),
                        "omega_body_deg_s": w.tolist()})
    for _ in range(8):  # the golden grid: spin about body z = orbital z, 3.5–4 °/s, phase 0–20°
        phase = np.radians(rng.uniform(0.0, 20.0))
        q = np.array([np.cos(phase / 2), 0.0, 0.0, np.sin(phase / 2)])
        out.append({"name": f"query_{len(out)}", "command": "query", "kind": "flat_spin", "table": str(table),
                    "attitude_wxyz": q.tolist(), "omega_body_deg_s": [0.0, 0.0, float(rng.uniform(3.5, 4.0))]})
    return out


def run(case: dict, out_dir: Path) -> dict:
    """Run one case through the CLI, keep its plan thinned; the case with its exit code."""
    plan_json = out_dir / f"{case['name']}.json"
    cli = [str(ROOT / ".venv" / "bin" / "lutgen")]
    state = ["--attitude", ",".join(f"{v:.12g}" for v in case["attitude_wxyz"]),
             "--omega-deg-s", ",".join(f"{v:.12g}" for v in case["omega_body_deg_s"]), "--out", str(plan_json)]
    args = ([*cli, "plan", case["scenario"], *state] if case["command"] == "plan"
            else [*cli, "query", case["table"], *state])
    try:
        proc = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=PLAN_TIMEOUT_S)
        code, tail = proc.returncode, (proc.stdout + proc.stderr).strip().splitlines()[-1:]
    except subprocess.TimeoutExpired:
        code, tail = None, [f"timed out after {PLAN_TIMEOUT_S} s"]
    result = dict(case, exit_code=code, last_line=tail[0] if tail else "")
    if plan_json.is_file():
        thin_to(plan_json, out_dir / f"{case['name']}.json.gz")
        plan_json.unlink()
        result["plan"] = f"{case['name']}.json.gz"
    print(f"{case['name']}: exit {code} {result['last_line'][:100]}", flush=True)
    return result


def thin_to(plan_json: Path, out: Path, step_s: float = 0.1) -> None:
    """The plan with its samples on a ``step_s`` grid (phase boundaries and the last sample kept), gzipped."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from make_plan_testdata import thin

    doc = json.loads(plan_json.read_text(encoding="utf-8"))
    t = np.asarray(doc["samples"]["t"])
    idx = thin(t, step_s, sorted({b for span in doc["phases"].values() for b in span}))
    doc["samples"] = {key: [value[i] for i in idx] for key, value in doc["samples"].items()}
    with gzip.open(out, "wt", encoding="utf-8", compresslevel=9) as fh:
        json.dump(doc, fh, separators=(",", ":"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="tests/data/truth")
    ap.add_argument("--table", default="tests/data/ci_golden.h5")
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--only", help="comma-separated case names to (re)run")
    args = ap.parse_args()
    out_dir = ROOT / args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    todo = cases(np.random.default_rng(SEED), Path(args.table))
    if args.only:
        todo = [c for c in todo if c["name"] in set(args.only.split(","))]
    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda c: run(c, out_dir), todo))
    index_path = out_dir / "index.json"
    index = {r["name"]: r for r in json.loads(index_path.read_text())} if index_path.is_file() else {}
    index.update({r["name"]: r for r in results})
    index_path.write_text(json.dumps(sorted(index.values(), key=lambda r: r["name"]), indent=1) + "\n")


if __name__ == "__main__":
    main()
