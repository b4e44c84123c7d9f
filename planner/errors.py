"""Exception types a user can cause; the CLI prints them in one line and exits non-zero."""


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


class TargetStateError(LutgenError):
    """An observed target state is invalid (NaN, non-unit quaternion, outside a table's grid, ...)."""
