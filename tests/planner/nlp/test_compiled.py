"""Compiled CasADi Functions (planner.nlp.compiled): same numbers as the interpreted Function, compiled once per
machine and source, shared safely between processes, and a quiet fallback when compiling is impossible.

A tiny Function compiles in well under a second, so these tests compile for real.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from planner.nlp import compiled as compiled_module
from planner.nlp.compiled import compiled


def _function(name: str = "toy", scale: float = 1.0) -> ca.Function:
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2)
    y = ca.vertcat(scale * ca.sin(x[0]) * p[0] + x[1] ** 3, ca.exp(x[2] * p[1]) / (1 + x[0] ** 2))
    return ca.Function(name, [x, p], [y, ca.sumsqr(x)], ["x", "p"], ["y", "s"])


@pytest.fixture()
def cache(tmp_path, monkeypatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("LUTGEN_CACHE_DIR", str(folder))
    monkeypatch.setenv("LUTGEN_COMPILE", "1")
    monkeypatch.setattr(compiled_module, "fallback_reasons", [])
    return folder


def _assert_same(f: ca.Function, g: ca.Function, x: np.ndarray, p: np.ndarray) -> None:
    for a, b in zip(f(x, p), g(x, p), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    outs = f(x, p)
    for a, b in zip(f.jacobian()(x, p, *outs), g.jacobian()(x, p, *outs), strict=True):
        np.testing.assert_array_equal(np.asarray(ca.DM(a)), np.asarray(ca.DM(b)))


def test_compiled_function_and_jacobian_equal_the_interpreted_ones_bit_for_bit(cache):
    f = _function()
    g = compiled(f)
    assert g.is_a("External") and not f.is_a("External")
    libraries = list(cache.glob("toy-*.so"))
    assert len(libraries) == 1
    rng = np.random.default_rng(3)
    for _ in range(5):
        _assert_same(f, g, rng.normal(size=3), rng.normal(size=2))
    # inside an MX graph CasADi differentiates the external through its compiled Jacobian
    X = ca.MX.sym("X", 3)
    jac = [ca.Function("J", [X], [ca.jacobian(fn(X, ca.DM([0.3, -0.7]))[0], X)]) for fn in (f, g)]
    np.testing.assert_array_equal(np.asarray(jac[0]([0.1, 0.2, 0.3])), np.asarray(jac[1]([0.1, 0.2, 0.3])))


def test_without_its_jacobian_a_function_compiles_alone_into_a_library_of_its_own(cache):
    """``with_jacobian=False``: the same numbers bit for bit, a library of its own (next to the one with the
    Jacobian, never mistaken for it), and no compiled Jacobian in it (CasADi derives one when asked)."""
    f = _function()
    g = compiled(f, with_jacobian=False)
    assert g.is_a("External")
    rng = np.random.default_rng(4)
    for _ in range(5):
        x, p = rng.normal(size=3), rng.normal(size=2)
        for a, b in zip(f(x, p), g(x, p), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    (alone,) = cache.glob("toy-*.so")
    assert alone.name.endswith("-nojac.so")
    compiled(f)
    (with_jacobian,) = set(cache.glob("toy-*.so")) - {alone}
    symbols = [ctypes.CDLL(str(lib)) for lib in (alone, with_jacobian)]
    assert hasattr(symbols[0], "toy") and not hasattr(symbols[0], "jac_toy")
    assert hasattr(symbols[1], "jac_toy")


def test_a_cached_library_is_loaded_without_compiling_again(cache, monkeypatch):
    compiled(_function())
    library = next(cache.glob("toy-*.so"))
    stamp = library.stat().st_mtime_ns

    def no_compiler(*args, **kwargs):
        raise AssertionError("compiled again")

    with monkeypatch.context() as patch:
        patch.setattr(subprocess, "run", no_compiler)
        g = compiled(_function())
    assert g.is_a("External") and library.stat().st_mtime_ns == stamp
    assert compiled_module.fallback_reasons == []
    # another formula under the same name is another expression graph, hence another library
    compiled(_function(scale=2.0))
    assert len(list(cache.glob("toy-*.so"))) == 2


def test_without_a_compiler_the_interpreted_function_is_used_and_the_reason_given(cache, monkeypatch):
    monkeypatch.setenv("CC", str(cache / "no-such-compiler"))
    f = _function()
    with pytest.warns(RuntimeWarning, match="toy: not compiled, interpreted instead .*FileNotFoundError"):
        g = compiled(f)
    assert g is f
    assert len(compiled_module.fallback_reasons) == 1
    # a compiler that fails is reported with its message
    monkeypatch.setenv("CC", "false")
    other = _function("other")
    with pytest.warns(RuntimeWarning, match="false exited with 1 compiling other"):
        assert compiled(other) is other
    assert not list(cache.glob("*.so"))


def test_compilation_can_be_switched_off(cache, monkeypatch):
    monkeypatch.setenv("LUTGEN_COMPILE", "0")
    f = _function()
    assert compiled(f) is f
    assert not cache.exists()


def test_a_library_that_disagrees_with_the_function_is_not_used(cache, monkeypatch):
    compiled(_function())
    # a compiler whose libraries never give the Function's numbers (a cached impostor is compiled again,
    # tests/planner/nlp/test_hardening_compiled.py; this one disagrees after that too)
    monkeypatch.setattr(compiled_module, "_agrees", lambda *args: False)
    f = _function()
    with pytest.warns(RuntimeWarning, match="disagrees with the interpreted Function"):
        assert compiled(f) is f


def test_processes_racing_for_one_library_compile_it_once(cache, tmp_path):
    """Two processes ask for the same library at once: the lock makes one compile and the other wait."""
    log = tmp_path / "compiler.log"
    wrapper = tmp_path / "cc-wrapper"
    wrapper.write_text(f"#!/bin/sh\necho run >> {log}\nsleep 1\nexec cc \"$@\"\n")
    wrapper.chmod(0o755)
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_compiled import _function
        from planner.nlp.compiled import compiled
        g = compiled(_function())
        assert g.is_a("External"), "fell back"
        print(float(g([0.1, 0.2, 0.3], [0.4, 0.5])[0][0]))
    """)
    env = {**os.environ, "CC": str(wrapper), "LUTGEN_CACHE_DIR": str(cache)}
    procs = [subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    assert log.read_text().split() == ["run"]
    expected = float(_function()([0.1, 0.2, 0.3], [0.4, 0.5])[0][0])
    assert [float(o.strip()) for o, _ in outs] == [expected, expected]


def _logging_compiler(tmp_path: Path) -> tuple[Path, Path]:
    """A ``cc`` that logs its arguments, one line a run; its path and the log's."""
    log = tmp_path / "compiler.log"
    wrapper = tmp_path / "cc-logging"
    wrapper.write_text(f"#!/bin/sh\necho \"$@\" >> {log}\nexec cc \"$@\"\n")
    wrapper.chmod(0o755)
    return wrapper, log


def test_an_optimized_library_is_compiled_when_asked_for_and_loaded_by_every_process_after(cache, tmp_path,
                                                                                           monkeypatch):
    """``LUTGEN_COMPILE_OPTIMIZED=1``: ``-O1`` without multiply-add fusion, the numbers bit for bit the interpreted
    Function's; once cached, a process that does not ask for it loads it (no compiler run, no ``-O0`` library)."""
    wrapper, log = _logging_compiler(tmp_path)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.setenv(compiled_module.OPTIMIZE_ENV, "1")
    f = _function()
    g = compiled(f)
    (run,) = log.read_text().splitlines()
    assert "-O1" in run.split() and "-ffp-contract=off" in run.split() and "-O0" not in run.split()
    rng = np.random.default_rng(5)
    for _ in range(5):
        _assert_same(f, g, rng.normal(size=3), rng.normal(size=2))
    monkeypatch.delenv(compiled_module.OPTIMIZE_ENV)
    assert compiled(_function()).is_a("External")
    assert len(log.read_text().splitlines()) == 1 and len(list(cache.glob("toy-*.so"))) == 1


def test_without_the_request_a_library_is_compiled_at_O0_under_the_name_it_always_had(cache, tmp_path, monkeypatch):
    """The ``-O0`` library keeps its name (a hash of the graph, the CasADi version, the compiler and the flags), so a
    cache filled before ``-O1`` existed is still used."""
    import hashlib

    wrapper, log = _logging_compiler(tmp_path)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.delenv(compiled_module.OPTIMIZE_ENV, raising=False)
    f = _function()
    assert compiled(f).is_a("External")
    (run,) = log.read_text().splitlines()
    assert "-O0" in run.split() and "-O1" not in run.split()
    key = hashlib.sha256("\0".join([f.serialize(), ca.__version__, str(wrapper), "-shared", "-fPIC", "-O0"]).encode())
    assert [p.name for p in cache.glob("toy-*.so")] == [f"toy-{key.hexdigest()[:24]}.so"]
