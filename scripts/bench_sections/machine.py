"""``machine``: what the numbers were measured on."""

from __future__ import annotations

import importlib.metadata
import os
import platform
import time
from pathlib import Path
from typing import Any

from bench_sections.common import Settings

# distribution name (what importlib.metadata knows) → import name, where they differ it matters to readers
LIBRARIES = {"numpy": "numpy", "scipy": "scipy", "pin": "pinocchio", "casadi": "casadi", "python-fcl": "fcl",
             "h5py": "h5py", "joblib": "joblib", "distributed": "distributed", "lutgen": "lut, planner"}


def _cpu_model() -> str:
    """The CPU model name (platform.processor() is often empty on Linux)."""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text(errors="replace").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def load_average() -> list[float] | None:
    """1/5/15-min load averages: another job on the machine shows here (None where unsupported)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def machine(settings: Settings) -> dict[str, Any]:
    """CPU count and model, platform, Python, library versions, mode, timestamp, load at the start."""
    return {
        "cpu_count": os.cpu_count(),
        "cpu_model": _cpu_model(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": {dist: _version(dist) for dist in LIBRARIES},
        "import_names": LIBRARIES,
        "mode": settings.mode,
        "trim": settings.trim,
        "seed": settings.seed,
        "timestamp_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "load_average_start": load_average(),
    }
