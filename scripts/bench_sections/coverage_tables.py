"""Which table of a folder answers each kind of coverage state: the one built for its scenario and motion, else
(a flat spin being a tumble) a tumble table of its scenario."""

from __future__ import annotations

from pathlib import Path

from bench_sections.common import relative


def table_identity(path: Path) -> tuple[str, str]:
    """``(scenario name, grid kind)`` a table was built for (its root attributes; refused tables raise)."""
    from lut.table.store import Table
    from planner.config.variant import identity_name

    attrs = Table.open(path).attrs
    return identity_name(attrs["scenario_text"]), str(attrs["grid_kind"])


def find_tables(folder: Path, kinds: list[tuple[str, str, str]]) -> tuple[dict[str, Path], list[str]]:
    """``{kind name: table}`` for ``kinds`` = ``(name, scenario, motion)``, and one line per table found (or
    refused) saying what it was taken for; the first table in name order wins."""
    found: dict[tuple[str, str], Path] = {}
    lines = []
    for path in sorted(folder.glob("*.h5")) if folder.is_dir() else []:
        try:
            identity = table_identity(path)
        except Exception as exc:  # noqa: BLE001 - a table the query would refuse is no table for the bench
            lines.append(f"{relative(path)}: refused ({str(exc).splitlines()[0]})")
            continue
        found.setdefault(identity, path)
        lines.append(f"{relative(path)}: {identity[0]} {identity[1]}")
    tables = {}
    for name, scenario, motion in kinds:
        table = found.get((scenario, motion)) or (found.get((scenario, "tumble")) if motion == "flat_spin" else None)
        if table is not None:
            tables[name] = table
    return tables, lines
