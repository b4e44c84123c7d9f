"""Output paths checked before any computing: never an input, in a writable folder, no table clobbered.

A table is a night of computing and a scenario is someone's work: a command refuses, before it solves
anything, to write where one of its inputs is, into a missing or read-only folder, or over a file that
is a look-up table or build journal (``lutgen build --force`` overwrites its own table on purpose).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from lut.table.journal_format import MAGIC as JOURNAL_SIGNATURE
from planner.errors import LutgenError

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


class OutputPathError(LutgenError):
    """An output path would replace an input or a table, or its folder is missing or not writable."""


@dataclass(frozen=True)
class Output:
    """One file a command will write: the option that names it (for the message) and its path."""

    option: str
    path: Path


def _same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name one file (same resolved path, or hard/symbolic links to one inode)."""
    if a.resolve() == b.resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet): only the resolved paths can tell
        return False


def holds_table(path: Path) -> bool:
    """True when ``path`` is an existing HDF5 file or lutgen build journal (by its first bytes)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(JOURNAL_SIGNATURE))
    except OSError:
        return False
    return head.startswith(HDF5_SIGNATURE) or head == JOURNAL_SIGNATURE


def _check_folder(out: Output) -> None:
    folder = out.path.absolute().parent
    if not folder.is_dir():
        raise OutputPathError(f"{out.option} {out.path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{out.option} {out.path}: folder {folder} is not writable")
    if out.path.is_dir():
        raise OutputPathError(f"{out.option} {out.path}: is a folder, expected a file path")
    if out.path.exists() and not os.access(out.path, os.W_OK):
        raise OutputPathError(f"{out.option} {out.path}: exists and is not writable")


def check_outputs(inputs: Iterable[str | Path], outputs: Iterable[Output], *, tables_allowed: bool = False,
                  creates_folders: bool = False) -> None:
    """Raise :class:`OutputPathError` unless every output may be written.

    Refused: an output that is one of ``inputs`` or another output, a missing (unless the command
    ``creates_folders``) or read-only folder, an existing folder in its place, and (unless
    ``tables_allowed``) an existing look-up table or journal.
    """
    input_paths = [Path(p) for p in inputs]
    seen: list[Output] = []
    for out in outputs:
        for given in input_paths:
            if _same_file(out.path, given):
                raise OutputPathError(f"{out.option} {out.path}: is an input of this command ({given}); "
                                      "choose another output path")
        for other in seen:
            if _same_file(out.path, other.path):
                raise OutputPathError(f"{out.option} {out.path}: is also the {other.option} output")
        if not creates_folders:
            _check_folder(out)
        if not tables_allowed and holds_table(out.path):
            raise OutputPathError(f"{out.option} {out.path}: is a look-up table or build journal; "
                                  "refusing to overwrite it")
        seen.append(out)
