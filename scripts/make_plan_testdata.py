"""Shrink a plan JSON into test data: every field kept, samples thinned to a coarser fixed step, gzip.

    .venv/bin/python scripts/make_plan_testdata.py PLAN.json OUT.json.gz [--step-s 0.1]

Used for ``tests/data/plan_I.json.gz``, ``plan_II.json.gz`` and ``plan_II_replay.json.gz`` (``--step-s 0.5``)
(``lutgen plan … --out PLAN.json`` first).
Phase boundaries and the last sample are always kept.
"""

from __future__ import annotations

import argparse
import gzip
import json
from pathlib import Path

import numpy as np

from lut.output.plan_file import check_plan


def thin(t: np.ndarray, step_s: float, boundaries: list[float]) -> np.ndarray:
    """Indices of the samples on the coarser grid ``t[0] + k·step_s``, plus the last one and phase boundaries."""
    k = np.round((t - t[0]) / step_s)
    on_grid = np.abs(t - t[0] - k * step_s) < 1e-6
    keep = set(np.flatnonzero(on_grid).tolist()) | {len(t) - 1}
    for b in boundaries:
        keep |= set(np.flatnonzero(np.abs(t - b) < 1e-6).tolist())
    return np.array(sorted(keep))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plan")
    ap.add_argument("out")
    ap.add_argument("--step-s", type=float, default=0.1)
    args = ap.parse_args()
    doc = json.loads(Path(args.plan).read_text(encoding="utf-8"))
    check_plan(doc, args.plan)
    s = doc["samples"]
    t = np.asarray(s["t"])
    idx = thin(t, args.step_s, sorted({b for span in doc["phases"].values() for b in span}))
    doc["samples"] = s = {key: [value[i] for i in idx] for key, value in s.items()}
    with gzip.open(args.out, "wt", encoding="utf-8", compresslevel=9) as fh:
        json.dump(doc, fh, separators=(",", ":"))
    print(f"{args.out}: {len(idx)} samples (of {len(t)}), {Path(args.out).stat().st_size} bytes")


if __name__ == "__main__":
    main()
