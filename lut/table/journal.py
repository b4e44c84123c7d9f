"""Crash-safe build journal: an append-only file of checksummed records, one per finished grid point.

A build solves points for hours and must survive ``kill -9`` (or a power cut) at any moment, then
resume. Every finished point is appended with ONE ``os.write`` of a self-contained frame followed by
``os.fsync``; a frame torn by a crash mid-write fails its length/checksum test, is ignored on read and
cut away before the next append. An exclusive ``flock`` (POSIX) keeps two builds from appending to the
same journal at once; the kernel drops it when the process dies. The journal is created *under* that
lock (``O_CREAT`` on the one path, then the lock, then the header), so of two builds starting at the
same moment exactly one gets it and the other is refused; a journal that holds only the beginning of
its own header (a crash while creating it) holds no records either and is started again. :func:`journal_status` tells a
running build's journal from an interrupted one's.

The file format: :mod:`lut.table.journal_format`.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

from lut.table.durable import fsync_dir
from lut.table.journal_format import MAGIC, decode_record, encode_frame, encode_record, read_frames
from lut.table.schema import TableError

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

def _header_digest(header: dict[str, str]) -> str:
    return hashlib.sha256(json.dumps(header, sort_keys=True).encode("utf-8")).hexdigest()[:12]


class JournalStatus(Enum):
    """What is at a journal's path: nothing, a running build's journal, or an interrupted build's."""

    ABSENT = "absent"
    IN_USE = "in use"  # a running build holds its lock
    INTERRUPTED = "interrupted"  # unlocked: its build stopped before the table was complete


def journal_status(path: Path) -> JournalStatus:
    """The :class:`JournalStatus` of ``path`` (probes the lock without taking it for longer than the probe)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return JournalStatus.ABSENT
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return JournalStatus.IN_USE
        return JournalStatus.INTERRUPTED
    finally:
        os.close(fd)


class Journal:
    """An append-only, crash-safe journal of point records (see the module docstring for the format).

    ``header`` identifies what the journal belongs to (config hash etc.); opening an existing journal
    with a different header raises :class:`~lut.table.schema.TableError`. A record must hold an int
    ``"point"`` and a str ``"status"``; :meth:`records` returns the last record of every point,
    :meth:`first_records` the first (a point journaled again, e.g. polished, keeps both).
    ``ignored_bytes`` says how much of a torn tail was cut away on open; ``started`` is True when this
    open wrote the header (a new journal), False when it continues an existing one.
    """

    def __init__(self, path: Path, header: dict[str, str]) -> None:
        self.path = Path(path)
        self.header = {str(k): str(v) for k, v in header.items()}
        self.ignored_bytes = 0
        self.started = False
        self._records: dict[int, dict[str, Any]] = {}
        self._first: dict[int, dict[str, Any]] = {}
        self._fd: int | None = None
        fd = self._open_locked()
        try:
            self._load(fd)
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd

    def _open_locked(self) -> int:
        """A descriptor of the file now at ``path`` (created if missing), under an exclusive lock."""
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
            if fcntl is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    os.close(fd)
                    raise TableError(f"journal {self.path} is in use by another build (still running)") from None
            try:
                if os.stat(self.path).st_ino == os.fstat(fd).st_ino:
                    return fd
            except FileNotFoundError:
                pass
            os.close(fd)  # a finishing build removed or replaced the file between our open and lock: again

    def _head(self) -> bytes:
        """The bytes a journal with this header starts with."""
        return MAGIC + encode_frame(encode_record(self.header))

    def _start(self, fd: int) -> None:
        """Write the header into an empty (or torn-while-created) journal, durably."""
        os.ftruncate(fd, 0)
        data = self._head()
        if os.write(fd, data) != len(data):
            raise OSError(f"short write to {self.path}")
        os.fsync(fd)
        fsync_dir(self.path.parent)
        self.started = True

    def _load(self, fd: int) -> None:
        size = os.fstat(fd).st_size
        data = os.pread(fd, size, 0) if hasattr(os, "pread") else self.path.read_bytes()
        if self._head().startswith(data):  # new, or torn while this same header was written: no records yet
            self._start(fd)
            return
        if not data.startswith(MAGIC):
            raise TableError(f"{self.path} is not a lutgen journal (bad magic bytes)")
        payloads, end = read_frames(data, len(MAGIC))
        if not payloads:
            raise TableError(f"journal {self.path} is corrupt (no intact header); delete it to start over")
        stored = decode_record(payloads[0])
        if stored != self.header:
            differ = sorted(k for k in stored.keys() | self.header.keys() if stored.get(k) != self.header.get(k))
            raise TableError(
                f"journal {self.path} was written for a different config (hash {_header_digest(stored)}, this build "
                f"{_header_digest(self.header)}; differs in {', '.join(differ)}): delete it to start over")
        for payload in payloads[1:]:
            self._keep(decode_record(payload))
        if end < size:  # a torn or corrupt tail: cut it away before anything is appended after it
            self.ignored_bytes = size - end
            os.ftruncate(fd, end)
            os.fsync(fd)

    def append(self, record: dict[str, Any]) -> None:
        """Append ``record`` durably (one ``os.write`` of one frame, then ``os.fsync``)."""
        if self._fd is None:
            raise ValueError(f"journal {self.path} is closed")
        point = record.get("point")
        if isinstance(point, bool) or not isinstance(point, int | np.integer):
            raise TableError(f"journal record: 'point' must be an int, got {point!r}")
        if not isinstance(record.get("status"), str):
            raise TableError(f"journal record for point {point}: 'status' must be a str, got "
                               f"{record.get('status')!r}")
        payload = encode_record(record)
        frame = encode_frame(payload)
        end = os.fstat(self._fd).st_size
        try:
            written = os.write(self._fd, frame)
            if written != len(frame):
                raise OSError(f"short write to {self.path}: {written} of {len(frame)} bytes")
            os.fsync(self._fd)
        except OSError:
            with contextlib.suppress(OSError):  # leave no partial frame behind (e.g. disk full)
                os.ftruncate(self._fd, end)
            raise
        self._keep(decode_record(payload))

    def _keep(self, record: dict[str, Any]) -> None:
        point = int(record["point"])
        self._first.setdefault(point, record)
        self._records[point] = record

    def records(self) -> dict[int, dict[str, Any]]:
        """The last record of every point journaled so far (a fresh dict; records are decoded copies)."""
        return dict(self._records)

    def first_records(self) -> dict[int, dict[str, Any]]:
        """The first record of every point journaled so far (a fresh dict)."""
        return dict(self._first)

    def journaled_again(self) -> set[int]:
        """The points journaled more than once."""
        return {p for p, rec in self._records.items() if rec is not self._first[p]}

    def discard(self) -> None:
        """Close and delete the journal (a build that stopped before its first record leaves nothing behind)."""
        if self._fd is not None:
            with contextlib.suppress(FileNotFoundError):
                if os.stat(self.path).st_ino == os.fstat(self._fd).st_ino:
                    self.path.unlink()
        self.close()

    def close(self) -> None:
        """Release the file (and its lock). Idempotent."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
