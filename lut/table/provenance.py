"""Where a table's reused plans came from: the root attribute ``reused_from`` that ``lutgen build --reuse`` writes."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from lut.table.schema import TableError


@dataclass(frozen=True)
class ReusedSource:
    """One table a build reused: its path relative to the new table's folder, when it was built (ISO 8601 UTC) and
    the new table's points taken from it (a table given whose plans were all dearer has none)."""

    table: str
    created_utc: str
    points: tuple[int, ...]

    def as_json(self) -> dict[str, str | list[int]]:
        """The source as the attribute's JSON holds it (and ``lutgen inspect --json`` prints it)."""
        return {"table": self.table, "created_utc": self.created_utc, "points": list(self.points)}


def provenance_text(sources: Sequence[ReusedSource]) -> str:
    """The attribute's text: a JSON list of :meth:`ReusedSource.as_json`, in the order given."""
    return json.dumps([s.as_json() for s in sources])


def reused_sources(path: Path, text: str | None, n_points: int) -> tuple[ReusedSource, ...]:
    """The attribute read back (none without it); :class:`TableError` naming ``path`` unless it is such a list with
    each point inside ``0 … n_points − 1`` and taken from one table only."""
    if text is None:
        return ()
    try:
        items = json.loads(text)
        sources = tuple(ReusedSource(_text(d["table"]), _text(d["created_utc"]),
                                     tuple(_index(p, n_points) for p in d["points"])) for d in items)
    except (ValueError, TypeError, KeyError) as exc:
        raise TableError(f"{path}: root attribute reused_from is not a list of reused tables ({exc})") from None
    taken = [p for s in sources for p in s.points]
    if len(set(taken)) != len(taken):
        raise TableError(f"{path}: root attribute reused_from takes a point from more than one table")
    return sources


def _text(value: object) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{value!r} is not text")
    return value


def _index(value: object, n_points: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n_points:
        raise ValueError(f"point {value!r} is not in 0..{n_points - 1}")
    return value
