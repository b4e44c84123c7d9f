"""CasADi Functions compiled to C and cached on disk: the hot inner Functions of the NLPs.

An NLP's constraint Jacobian pushes every decision direction through each call of its inner SX Functions,
which CasADi evaluates in its virtual machine. The same expressions generated as C and compiled run several
times faster with the same results, bit for bit: C without fast-math performs the same floating-point
operations in the same order.

A library holds the Function and its Jacobian (``jac_<name>``, which CasADi looks up when it differentiates
an external Function). It is compiled once per machine and cached under :func:`cache_dir`, named by a hash of
the Function's serialisation (its whole expression graph, far quicker to form than the C),
the CasADi version and the compiler, so any change of robot, formula or CasADi version compiles anew, and a
library that does not give the Function's numbers is never used (checked at every load). Compilation runs
under a file lock, so a table build's workers wait for one compiler instead of racing, and the library
appears by atomic rename, so no process ever loads half of one. A cached library that cannot be loaded or
gives other numbers (truncated by a full disk, copied from another machine) is deleted and compiled once more.

``-O0`` by default: the sources are large (megabytes of straight-line code), and a plan on a fresh machine compiles
inside its own time budget. With :data:`OPTIMIZE_ENV` set (an operator preparing a machine, an overnight build) what
is missing is compiled at ``-O1``, which takes several times longer, once per machine (README, "Compiled inner
Functions"), and evaluates the NLPs' Jacobians faster; once such a library is cached every process loads it, a live
plan included. ``-ffp-contract=off`` keeps the optimiser from fusing a multiply and an add (FMA), so that both levels
give the same numbers.

Without a C compiler (or with ``LUTGEN_COMPILE=0``) the SX Function itself is used: the same answers, more
slowly. :func:`compiled` never fails because of compilation; it says why it fell back in
:data:`fallback_reasons` and in one warning per process.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

COMPILE_FLAGS = ("-shared", "-fPIC", "-O0")  # the default: quick to compile (a fresh machine's first plan)
OPTIMIZED_FLAGS = ("-shared", "-fPIC", "-O1", "-ffp-contract=off")
OPTIMIZE_ENV = "LUTGEN_COMPILE_OPTIMIZED"  # "1": a library not yet cached is compiled with OPTIMIZED_FLAGS
COMPILE_TIMEOUT_S = 900.0
# compiled and interpreted results agree bit for bit; the check allows a few ulps of headroom in case a
# compiler contracts a multiply-add (FMA), which changes the last bit
AGREEMENT_RTOL = 1e-12

fallback_reasons: list[str] = []


def cache_dir() -> Path:
    """Where compiled libraries live: ``$LUTGEN_CACHE_DIR``, else ``$XDG_CACHE_HOME/lutgen``, else
    ``~/.cache/lutgen``."""
    if os.environ.get("LUTGEN_CACHE_DIR"):
        return Path(os.environ["LUTGEN_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "lutgen"


def compile_enabled() -> bool:
    """False when ``LUTGEN_COMPILE`` is ``0``/``false``/``no``/``off``."""
    return os.environ.get("LUTGEN_COMPILE", "1").strip().lower() not in ("0", "false", "no", "off")


def optimize_wanted() -> bool:
    """True when :data:`OPTIMIZE_ENV` is ``1``/``true``/``yes``/``on``: compile what is missing with ``-O1``."""
    return os.environ.get(OPTIMIZE_ENV, "0").strip().lower() in ("1", "true", "yes", "on")


def compiled(f: ca.Function, options: dict | None = None, with_jacobian: bool = True) -> ca.Function:
    """``f`` (an SX Function) with its Jacobian, compiled and loaded, or ``f`` itself if that is not possible.

    ``options``: Function options the returned Function keeps (e.g. ``jac_penalty``). ``with_jacobian=False``:
    ``f`` alone, for a Function only evaluated numerically (its Jacobian may be far larger to compile).
    """
    if not compile_enabled():
        return f
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        return _fall_back(f, "no C compiler found (set CC, or install gcc)")
    jacobian = f.jacobian() if with_jacobian else None
    entry = _CacheEntry.of(f, compiler, with_jacobian)
    problem = ""
    for attempt in range(2):  # a cached library that cannot be loaded or disagrees is compiled once more
        flags = entry.flags()
        try:
            library = _library(entry, f, jacobian, compiler, flags)
            loaded = ca.external(f.name(), str(library), dict(options or {}))
        except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
            problem = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        else:
            if _agrees(f, jacobian, loaded):
                return loaded
            problem = f"the compiled {library.name} disagrees with the interpreted Function"
            del loaded  # unloads it: a library still loaded would be found again by the next dlopen of its path
        if attempt == 1 or not _discard_cached(entry, flags):
            break
    return _fall_back(f, problem)


@dataclass(frozen=True)
class _CacheEntry:
    """One Function's place in the cache: a library (and its lock file) per set of compiler flags."""

    name: str
    source: str  # what the libraries are named by: the expression graph, the CasADi version, the compiler
    with_jacobian: bool

    @classmethod
    def of(cls, f: ca.Function, compiler: str, with_jacobian: bool) -> _CacheEntry:
        """The entry of ``f`` (and its Jacobian, if ``with_jacobian``) compiled by ``compiler``."""
        return cls(f.name(), "\0".join([f.serialize(), ca.__version__, compiler]), with_jacobian)

    def paths(self, flags: tuple[str, ...]) -> tuple[Path, Path]:
        """The library compiled with ``flags`` and its lock file."""
        key = hashlib.sha256("\0".join([self.source, *flags]).encode())
        stem = f"{self.name}-{key.hexdigest()[:24]}" + ("" if self.with_jacobian else "-nojac")
        folder = cache_dir()
        return folder / f"{stem}.so", folder / f"{stem}.lock"

    def flags(self) -> tuple[str, ...]:
        """The flags of the library to load: ``-O1``'s when it is cached or wanted (:func:`optimize_wanted`), else
        ``-O0``'s."""
        optimized, _ = self.paths(OPTIMIZED_FLAGS)
        return OPTIMIZED_FLAGS if optimized.is_file() or optimize_wanted() else COMPILE_FLAGS


def _discard_cached(entry: _CacheEntry, flags: tuple[str, ...]) -> bool:
    """Delete ``entry``'s library compiled with ``flags`` (broken: truncated, foreign, or giving other numbers), under
    its lock; True when there was one to delete, so compiling again may help."""
    library, lock_path = entry.paths(flags)
    if not library.is_file():
        return False
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        library.unlink(missing_ok=True)
    return True


def _library(entry: _CacheEntry, f: ca.Function, jacobian: ca.Function | None, compiler: str,
             flags: tuple[str, ...]) -> Path:
    """The cached shared library of ``f`` and its Jacobian (if not None) compiled with ``flags``, compiled first if
    missing."""
    name = f.name()
    library, lock_path = entry.paths(flags)
    folder = library.parent
    folder.mkdir(parents=True, exist_ok=True)
    if library.is_file():
        return library
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another process may be compiling it: wait for it
        if library.is_file():
            return library
        generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        generator.add(f)
        if jacobian is not None:
            generator.add(jacobian)
        with tempfile.TemporaryDirectory(dir=folder, prefix=f".{name}-") as scratch:
            c_file = Path(scratch) / f"{name}.c"
            c_file.write_text(generator.dump())
            built = Path(scratch) / f"{name}.so"
            done = subprocess.run([compiler, *flags, str(c_file), "-o", str(built), "-lm"],
                                  capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S)
            if done.returncode != 0:
                output = (done.stderr or done.stdout).strip()[:300]
                raise RuntimeError(f"{compiler} exited with {done.returncode} compiling {name}"
                                   + (f": {output}" if output else ""))
            os.replace(built, library)
    return library


def _agrees(f: ca.Function, jacobian: ca.Function | None, loaded: ca.Function) -> bool:
    """Both Functions, and their Jacobians (when compiled with one), give the same numbers at a fixed point (seeded)."""
    rng = np.random.default_rng(0)
    args = [rng.uniform(0.5, 1.5, f.size_in(i)) for i in range(f.n_in())]
    outs = f(*args)
    outs = [outs] if f.n_out() == 1 else list(outs)
    pairs = list(zip(outs, [loaded(*args)] if f.n_out() == 1 else loaded(*args), strict=True))
    if jacobian is not None:
        pairs += zip(jacobian(*args, *outs), loaded.jacobian()(*args, *outs), strict=True)
    for a, b in pairs:
        a, b = np.asarray(ca.DM(a)), np.asarray(ca.DM(b))
        scale = max(1.0, float(np.nanmax(np.abs(a), initial=0)))
        if not np.allclose(a, b, rtol=AGREEMENT_RTOL, atol=AGREEMENT_RTOL * scale, equal_nan=True):
            return False
    return True


def _fall_back(f: ca.Function, reason: str) -> ca.Function:
    message = f"{f.name()}: not compiled, interpreted instead ({reason})"
    if message not in fallback_reasons:
        fallback_reasons.append(message)
        warnings.warn(f"lutgen: {message}", RuntimeWarning, stacklevel=3)
    return f
