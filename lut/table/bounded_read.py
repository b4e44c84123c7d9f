"""A read of an untrusted file run first in a forked child with a time limit: a corrupt file that hangs or
crashes libhdf5 costs seconds and one error line, never the caller.

A damaged table can make libhdf5 spin inside the read of a root attribute, holding the GIL, deaf to
Ctrl-C; nothing in the file's structure can be checked before that attribute without re-implementing an
HDF5 parser. So ``os.fork`` of the caller (no new interpreter, no imports: far cheaper than a fresh
process) does the whole read and exits; only when it succeeded does the caller read the file itself.
The child's answer is its exit code and, on failure, one line through a pipe; no data crosses the
process boundary (no pickles).
"""

from __future__ import annotations

import os
import select
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

_EXIT_OK = 0
_EXIT_REFUSED = 3  # the read raised: its message is in the pipe
_MESSAGE_BYTES = 4096


class ProbeOutcome(Enum):
    OK = "ok"  # the read finished without an exception
    REFUSED = "refused"  # the read raised; ``detail`` holds its message
    TIMED_OUT = "timed out"  # killed at the time limit (libhdf5 hung)
    CRASHED = "crashed"  # the child died of a signal (libhdf5 crashed)


@dataclass(frozen=True)
class Probe:
    outcome: ProbeOutcome
    detail: str = ""


def probe_read(read: Callable[[], object], timeout_s: float) -> Probe:
    """Run ``read()`` in a forked child, killed after ``timeout_s`` (s); where the OS cannot fork, the probe is
    skipped (:attr:`ProbeOutcome.OK`) and the caller's own read is the only one."""
    if not hasattr(os, "fork"):  # pragma: no cover - not POSIX
        return Probe(ProbeOutcome.OK)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: read, report, leave without running the parent's cleanup
        os.close(r)
        # its answer goes through the pipe: libhdf5 diagnostics or a crash dump must not reach the user's terminal
        os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
        code = _EXIT_OK
        try:
            read()
        except BaseException as exc:  # noqa: BLE001 - every failure is the answer
            os.write(w, str(exc).encode("utf-8", "replace")[:_MESSAGE_BYTES])
            code = _EXIT_REFUSED
        os._exit(code)
    os.close(w)
    try:
        message, finished = _read_until_eof(r, time.monotonic() + timeout_s)
    finally:
        os.close(r)
    if not finished:
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    if not finished:
        return Probe(ProbeOutcome.TIMED_OUT)
    if os.WIFSIGNALED(status):
        return Probe(ProbeOutcome.CRASHED, f"signal {os.WTERMSIG(status)}")
    if os.WEXITSTATUS(status) != _EXIT_OK:
        return Probe(ProbeOutcome.REFUSED, message.decode("utf-8", "replace"))
    return Probe(ProbeOutcome.OK)


def _read_until_eof(fd: int, deadline: float) -> tuple[bytes, bool]:
    """What the child writes to ``fd`` until it exits (EOF), and whether that came before ``deadline``."""
    chunks = []
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return b"".join(chunks), False
        ready, _, _ = select.select([fd], [], [], left)
        if not ready:
            continue
        chunk = os.read(fd, _MESSAGE_BYTES)
        if not chunk:
            return b"".join(chunks), True
        chunks.append(chunk)
