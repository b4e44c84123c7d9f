"""A solver process kept for a build's successive points: one planner per scenario built once, not once per point.

Each point still has its hard time limit and its own failure: a point over its limit kills the process, a crash
ends it, and either way that point alone is recorded failed; the next point starts a new process
(:func:`lut.solve.point_worker.serve` is the other end). One process per solver and per process that asks (a build's
loky or dask worker); it ends when its asker closes its stdin or dies.
"""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import IO

from lut.solve.point_worker import DONE_TOKEN


@dataclass
class ServedAnswer:
    """How a point's process ended: ``answered`` (OUT.npz written), else ``timed_out`` or crashed (``why``)."""

    answered: bool
    timed_out: bool = False
    why: str = ""


@dataclass
class _Server:
    process: subprocess.Popen
    stderr: IO[bytes]  # a temporary file: a pipe nobody reads could fill and stall the solver


class _Outcome(Enum):
    ANSWERED = "answered"
    ENDED = "ended"
    TIMED_OUT = "timed out"


_SERVERS: dict[str, _Server] = {}
STOP_WAIT_S = 5.0  # an idle kept process given this long to end on its own when stopped [s]


def solve_served(solver: str, in_path: Path, out_path: Path, timeout_s: float) -> ServedAnswer:
    """Ask the kept process of ``solver`` (started when there is none) to solve IN.npz into OUT.npz within
    ``timeout_s`` [s]; a process that runs over or dies is dropped (killed) and the answer says so."""
    server = _SERVERS.get(solver)
    if server is None or server.process.poll() is not None or not _ask(server, in_path, out_path):
        if server is not None:  # it ended while idle (e.g. the kernel's OOM killer): not this point's failure
            _drop(solver, timed_out=False)
        server = _SERVERS[solver] = _start(solver)
        if not _ask(server, in_path, out_path):
            return _drop(solver, timed_out=False)
    outcome = _wait_for_answer(server.process, out_path, timeout_s)
    if outcome is _Outcome.ANSWERED:
        return ServedAnswer(True)
    return _drop(solver, timed_out=outcome is _Outcome.TIMED_OUT)


def _ask(server: _Server, in_path: Path, out_path: Path) -> bool:
    """Send one point's request; False when the process can no longer be asked. Its stderr starts anew, so that a
    crash's reason is this point's."""
    server.stderr.seek(0)
    server.stderr.truncate()  # the child shares this file's offset: it writes from the start again
    try:
        server.process.stdin.write(f"{in_path} {out_path}\n".encode())
        server.process.stdin.flush()
    except (BrokenPipeError, OSError):
        return False
    return True


def _start(solver: str) -> _Server:
    stderr = tempfile.TemporaryFile()
    process = subprocess.Popen([sys.executable, "-m", "lut.solve.point_worker", "--serve", solver, str(os.getpid())],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=stderr)
    return _Server(process, stderr)


def _wait_for_answer(process: subprocess.Popen, out_path: Path, timeout_s: float) -> _Outcome:
    """Whether ``process`` said OUT.npz is written, ended first, or let ``timeout_s`` [s] pass (read unbuffered: a
    buffered reader could hold the answer line while the selector waits for more)."""
    end = time.monotonic() + timeout_s
    expected = f"{DONE_TOKEN} {out_path}".encode()
    fd = process.stdout.fileno()
    pending = b""
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while (left := end - time.monotonic()) > 0:
            if not sel.select(left):
                break
            chunk = os.read(fd, 65536)
            if not chunk:  # its stdout closed: the process ended (it may not be reaped yet)
                return _Outcome.ENDED
            *lines, pending = (pending + chunk).split(b"\n")
            if any(line.strip() == expected for line in lines):
                return _Outcome.ANSWERED
    return _Outcome.TIMED_OUT


def _drop(solver: str, timed_out: bool) -> ServedAnswer:
    """End and forget ``solver``'s process; the answer carries the last line it wrote on stderr."""
    server = _SERVERS.pop(solver)
    if server.process.poll() is None:
        server.process.kill()
    code = server.process.wait()
    server.process.stdout.close()
    server.stderr.seek(0)
    words = server.stderr.read().decode(errors="replace")
    server.stderr.close()
    return ServedAnswer(False, timed_out, "" if timed_out else crash_reason(code, words))


def crash_reason(returncode: int, stderr_text: str) -> str:
    """``worker crashed (signal N | exit code N): <its last line on stderr>``."""
    last = (stderr_text.strip().splitlines() or ["no output"])[-1]
    how = f"signal {-returncode}" if returncode < 0 else f"exit code {returncode}"
    return f"worker crashed ({how}): {last}"


def stop_all() -> None:
    """End every kept solver process of this process (stdin closed: an idle one ends at once), e.g. at the end of a
    build."""
    for solver in list(_SERVERS):
        server = _SERVERS.pop(solver)
        server.process.stdin.close()
        try:
            server.process.wait(timeout=STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            server.process.kill()
            server.process.wait()
        server.process.stdout.close()
        server.stderr.close()
