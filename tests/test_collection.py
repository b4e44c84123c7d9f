"""The test run collects every test file: pytest's default folder filter once skipped ``tests/lut/build`` (a folder
named ``build``), so ``lutgen build``'s tests never ran in CI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_test_file_is_collected():
    proc = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "slow or not slow"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    collected = {line.split("::")[0] for line in proc.stdout.splitlines() if "::" in line}
    files = {p.relative_to(ROOT).as_posix() for p in (ROOT / "tests").rglob("test_*.py")
             if "def test_" in p.read_text(encoding="utf-8")}
    assert "tests/lut/build/test_build.py" in files
    assert files == collected, {"not collected": sorted(files - collected), "unexpected": sorted(collected - files)}
