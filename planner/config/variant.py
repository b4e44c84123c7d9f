"""A scenario variant: a scenario file that ``extends`` another in its folder and overrides some of its fields.

A cost-weighted scenario differs from its base in a few weights only; a copy would drift from its base. The
variant names its base (``extends = "scenario_I.toml"``, a file in the same folder, so every relative path means
the same in both) and gives only what differs: its keys replace the base's, table by table. A base may not itself
extend another. The variant's identity (the text a table's model hash is taken of) is the base's text followed by
the variant's, so a change of either file makes a table built from it stale.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.config.toml_table import read_toml
from planner.errors import FieldValueError

EXTENDS = "extends"
TEXT_SEPARATOR = "\n# ---- extended by {name} ----\n"


@dataclass(frozen=True)
class ResolvedScenario:
    """A scenario file's fields with its base's merged in, its identity text, and its base file (None: no base)."""

    data: dict[str, Any]
    text: str
    base_path: Path | None


def resolve_variant(path: Path, data: dict[str, Any], text: str) -> ResolvedScenario:
    """The scenario at ``path``: its base's fields merged with its own when it extends one."""
    if EXTENDS not in data:
        return ResolvedScenario(data, text, None)
    base_path = _base_path(path, data[EXTENDS])
    base_data, base_text = read_toml(base_path)
    if EXTENDS in base_data:
        raise FieldValueError(str(path), EXTENDS, f"{base_path.name} extends another scenario itself (one level "
                                                  "only)", data[EXTENDS])
    own = {k: v for k, v in data.items() if k != EXTENDS}
    return ResolvedScenario(merged(base_data, own), base_text + TEXT_SEPARATOR.format(name=path.name) + text,
                            base_path)


def identity_name(text: str) -> str:
    """The scenario name an identity text declares (a table's ``scenario_text``): a variant's own ``name``, else its
    base's. The identity text of a variant is not one TOML document (both files declare their tables)."""
    parts = re.split(re.escape(TEXT_SEPARATOR).replace(re.escape("{name}"), ".*?"), text)
    for part in reversed(parts):
        name = tomllib.loads(part).get("name")
        if name is not None:
            return str(name)
    raise FieldValueError("scenario text", "name", "is missing", None)


def merged(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``override``'s keys replacing its own, tables merged key by key (recursively)."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merged(out[key], value)
        else:
            out[key] = value
    return out


def _base_path(path: Path, name: Any) -> Path:
    """The base file a variant names: a file name in the variant's own folder."""
    if not isinstance(name, str) or not name or Path(name).name != name:
        raise FieldValueError(str(path), EXTENDS, "must be the file name of a scenario in the same folder", name)
    base = path.parent / name
    if base.resolve() == path.resolve():
        raise FieldValueError(str(path), EXTENDS, "a scenario cannot extend itself", name)
    if not base.is_file():
        raise FieldValueError(str(path), EXTENDS, f"file not found: {base}", name)
    return base
