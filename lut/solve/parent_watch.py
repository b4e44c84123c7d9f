"""Ends a helper process when the process that started it dies, so a killed build leaves nothing running.

A build's loky workers wait up to 300 s for work before they exit, and a point's solver process runs
until its own time limit (``--point-timeout``, 900 s by default): without this, both would outlive a
``kill -9`` of the build by minutes. A daemon thread polls the parent's pid; when the process is orphaned
(re-parented to init or a subreaper) it exits at once, and its own children, orphaned in turn, follow. It removes
the scratch folders the process made with :func:`scratch_dir` first: ended by ``os._exit``, no ``finally`` of the
process runs, and each killed build left a ``lutgen-point-*`` folder per worker in the temporary folder.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

POLL_S = 0.5  # how often the parent is looked for (s): the delay between a build's death and its helpers'

_watching = False
_lock = threading.Lock()
_scratch: set[str] = set()  # this process's scratch folders still in use (scratch_dir)


def exit_with_parent(parent_pid: int | None = None) -> None:
    """Start (once per process) a thread that ends this process as soon as its parent process is gone.

    ``parent_pid``: the pid the parent passed down; when this process's parent is already another one
    (the parent died while this process started up), it ends at once.
    """
    global _watching
    parent = os.getppid()
    if parent_pid is not None and parent != parent_pid:
        os._exit(1)
    with _lock:
        if _watching:
            return
        _watching = True
    threading.Thread(target=_watch, args=(parent,), name="lutgen-parent-watch", daemon=True).start()


@contextmanager
def scratch_dir(prefix: str) -> Iterator[Path]:
    """A new folder in the temporary folder, removed on leaving the block, or when the watch ends this process."""
    path = tempfile.mkdtemp(prefix=prefix)
    with _lock:
        _scratch.add(path)
    try:
        yield Path(path)
    finally:
        with _lock:
            _scratch.discard(path)
        shutil.rmtree(path, ignore_errors=True)


def _watch(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(POLL_S)
    with _lock:
        for path in _scratch:
            shutil.rmtree(path, ignore_errors=True)
    os._exit(1)  # orphaned: nobody will read this process's result
