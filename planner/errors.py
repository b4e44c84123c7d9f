"""Exception types a user can cause; the CLI prints them in one line and exits non-zero.

Each failure a caller may want to tell apart has its own class, carrying what failed (the file, the dotted
field, the offending value); the message is the one line the CLI prints after ``error:``.
"""

from __future__ import annotations

from typing import Any


class LutgenError(Exception):
    """Base class of every error caused by user input (config, CLI argument, file, target state)."""


class ConfigError(LutgenError):
    """A configuration file is missing, malformed, or has a field with an invalid value.

    The message names the file and the field, e.g. ``targets/x.toml: mass_kg: must be > 0, got -3``.
    """

    MAX_PROBLEM_CHARS = 300  # a problem quoting a huge value is cut: the message stays one readable line

    def __init__(self, source: str, field: str, problem: str) -> None:
        self.source = source
        self.field = field
        if len(problem) > self.MAX_PROBLEM_CHARS:
            problem = problem[: self.MAX_PROBLEM_CHARS - 1] + "…"
        self.problem = problem
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {problem}")


class ConfigFileError(ConfigError):
    """The file itself cannot be read as a config: not there, too large, not UTF-8, not TOML or XML."""

    def __init__(self, source: str, problem: str) -> None:
        super().__init__(source, "", problem)


class MissingFieldError(ConfigError):
    """A required field is absent."""

    def __init__(self, source: str, field: str) -> None:
        super().__init__(source, field, "missing required field")


class UnknownFieldError(ConfigError):
    """A field the format does not have (a typo, or a field of another version)."""

    def __init__(self, source: str, field: str) -> None:
        super().__init__(source, field, "unknown field")


class FieldTypeError(ConfigError):
    """A field holds the wrong kind of value (a string for a number, a list of the wrong length, ...)."""

    def __init__(self, source: str, field: str, problem: str, value: Any = None) -> None:
        self.value = value
        super().__init__(source, field, problem)


class FieldValueError(ConfigError):
    """A field has the right type but a value that is not allowed (negative mass, min > max, not SPD, ...)."""

    def __init__(self, source: str, field: str, problem: str, value: Any = None) -> None:
        self.value = value
        super().__init__(source, field, problem)


class SanityLimitError(FieldValueError):
    """A value beyond a sanity limit of :mod:`planner.config.limits`: surely a typo, and hours of work."""


class RobotModelError(ConfigError):
    """The URDF reads, but is not a robot lutgen plans for: no single serial revolute chain, bad joint
    limits, unsupported collision geometry, a missing end-effector frame."""


class TargetStateError(LutgenError):
    """An observed target state is invalid (NaN, non-unit quaternion, outside a table's grid, ...)."""


class StateFieldError(TargetStateError):
    """One field of an observed target state is malformed (shape, NaN or inf); carries the field and value."""

    def __init__(self, field: str, problem: str, value: Any = None) -> None:
        self.field = field
        self.value = value
        super().__init__(f"{field}: {problem}")


class NonUnitQuaternionError(StateFieldError):
    """The observed attitude is not a unit quaternion; carries its norm."""

    def __init__(self, field: str, problem: str, norm: float) -> None:
        self.norm = norm
        super().__init__(field, problem, norm)
