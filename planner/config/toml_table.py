"""Reading TOML configs: the file, and one table's typed getters that name the dotted field on error."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.config.limits import MAX_CONFIG_BYTES, violation
from planner.errors import (
    ConfigError,
    ConfigFileError,
    FieldTypeError,
    FieldValueError,
    MissingFieldError,
    SanityLimitError,
    UnknownFieldError,
)

Array = NDArray[np.float64]

MISSING = object()  # the default of a required field


class TomlTable:
    """One TOML table being read: typed getters that name the field on error, and an unknown-key check."""

    def __init__(self, data: dict[str, Any], source: str, prefix: str = "") -> None:
        if not isinstance(data, dict):
            raise FieldTypeError(source, prefix or "(root)", "expected a table", data)
        self.data = data
        self.source = source
        self.prefix = prefix
        self.used: set[str] = set()

    def field(self, key: str) -> str:
        """The dotted path of ``key`` in this file (``phases.approach_s``)."""
        return f"{self.prefix}.{key}" if self.prefix else key

    def error(self, key: str, problem: str, value: Any = None) -> ConfigError:
        """A :class:`FieldValueError` naming this file and ``key``'s dotted field."""
        return FieldValueError(self.source, self.field(key), problem, value)

    def type_error(self, key: str, problem: str, value: Any) -> ConfigError:
        """A :class:`FieldTypeError` naming this file and ``key``'s dotted field."""
        return FieldTypeError(self.source, self.field(key), problem, value)

    def _limit_error(self, key: str, problem: str, value: Any) -> ConfigError:
        return SanityLimitError(self.source, self.field(key), problem, value)

    def get(self, key: str, default: Any) -> Any:
        """The raw value of ``key`` (marked as read), or ``default``; :data:`MISSING` makes it required."""
        self.used.add(key)
        if key in self.data:
            return self.data[key]
        if default is MISSING:
            raise MissingFieldError(self.source, self.field(key))
        return default

    def number(self, key: str, default: Any = MISSING, *, positive: bool = False,
               nonnegative: bool = False, integer: bool = False) -> float:
        """A finite number (an int when ``integer``), checked against its sign and its sanity limit."""
        value = self.get(key, default)
        if value is default and default is not MISSING:
            return value
        kinds = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kinds):
            raise self.type_error(key, f"expected {'an integer' if integer else 'a number'}, got {short_repr(value)}",
                                  value)
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value!r}", value)
        if positive and not value > 0:
            raise self.error(key, f"must be > 0, got {value!r}", value)
        if nonnegative and value < 0:
            raise self.error(key, f"must be >= 0, got {value!r}", value)
        problem = violation(self.field(key), value)
        if problem:
            raise self._limit_error(key, problem, value)
        return int(value) if integer else float(value)

    def string(self, key: str, default: Any = MISSING, choices: tuple[str, ...] | None = None) -> str:
        """A string, one of ``choices`` when given."""
        value = self.get(key, default)
        if not isinstance(value, str):
            raise self.type_error(key, f"expected a string, got {short_repr(value)}", value)
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}, got {short_repr(value)}", value)
        return value

    def boolean(self, key: str, default: Any = MISSING) -> bool:
        """``true`` or ``false``."""
        value = self.get(key, default)
        if not isinstance(value, bool):
            raise self.type_error(key, f"expected true or false, got {short_repr(value)}", value)
        return value

    def vector(self, key: str, length: int, default: Any = MISSING) -> Array:
        """A list of ``length`` finite numbers as a ``(length,)`` float array (None when the default is None)."""
        value = self.get(key, default)
        if value is default and default is not MISSING:
            return None if default is None else np.asarray(default, dtype=float)
        if (not isinstance(value, list) or len(value) != length
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
            raise self.type_error(key, f"expected a list of {length} numbers, got {short_repr(value)}", value)
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise self.error(key, f"must be finite, got {value!r}", value)
        problem = violation(self.field(key), float(np.abs(arr).max()))
        if problem:
            raise self._limit_error(key, f"every element {problem}", value)
        return arr

    def range_(self, key: str, default: Any = MISSING) -> tuple[float, float]:
        """``[min, max]`` with min <= max."""
        lo, hi = self.vector(key, 2, default)
        if lo > hi:
            raise self.error(key, f"min > max ({lo} > {hi})", (float(lo), float(hi)))
        return float(lo), float(hi)

    def table(self, key: str, default: Any = MISSING) -> TomlTable:
        """The sub-table ``key`` (an empty one when it is absent and has a default)."""
        value = self.get(key, {} if default is not MISSING else MISSING)
        return TomlTable(value, self.source, self.field(key))

    def tables(self, key: str, maximum: int | None = None) -> list[TomlTable]:
        """The non-empty array of tables ``[[key]]``, at most ``maximum`` of them."""
        value = self.get(key, MISSING)
        if not isinstance(value, list) or not value:
            raise self.type_error(key, "expected a non-empty array of tables ([[...]])", value)
        if maximum is not None and len(value) > maximum:
            raise self._limit_error(key, f"{len(value)} entries, at most {maximum} (sanity limit)", len(value))
        return [TomlTable(v, self.source, f"{self.field(key)}[{i}]") for i, v in enumerate(value)]

    def finish(self) -> None:
        """Refuse any key of this table no getter has read (a typo, or a field of another version)."""
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise UnknownFieldError(self.source, self.field(unknown[0]))


def short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 2-million-element list stays one short line)."""
    text = repr(value) if not isinstance(value, list) or len(value) <= limit else f"[{len(value)} items]"
    return text if len(text) <= limit else text[: limit - 1] + "…"


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """``text`` parsed as TOML; anything that is not a sane config is a :class:`ConfigError` naming ``source``."""
    if len(text) > MAX_CONFIG_BYTES:
        raise ConfigFileError(source, f"{len(text)} characters: too large for a config (at most {MAX_CONFIG_BYTES})")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigFileError(source, f"not valid TOML ({exc})") from None
    except RecursionError:  # tomllib recurses once per nesting level of an array or inline table
        raise ConfigFileError(source, "not a config: arrays or tables nested too deeply") from None


def read_toml(path: Path) -> tuple[dict[str, Any], str]:
    """The parsed TOML of the file at ``path`` and its text; a :class:`ConfigFileError` if it is not a config."""
    src = str(path)
    if not path.is_file():
        raise ConfigFileError(src, "file not found")
    if path.stat().st_size > MAX_CONFIG_BYTES:
        raise ConfigFileError(src, f"{path.stat().st_size} bytes: too large for a config (at most {MAX_CONFIG_BYTES})")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigFileError(src, "not valid TOML (not UTF-8 text)") from None
    return parse_toml(text, src), text
