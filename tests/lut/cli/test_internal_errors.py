"""An unexpected exception is lutgen's own failure: its traceback, a last line ``internal error: …`` and exit code 70,
never the exit code 1 of bad input (a script must not read a defect as a valid state refused)."""

from __future__ import annotations

import pytest

from lut.cli.exit_codes import ExitCode
from lut.cli.main import main
from lut.cli.user_errors import user_errors
from planner.errors import LutgenError
from tests.support.cli import ROOT, assert_one_line_error, lutgen_in_process

SCENARIO_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"


def _last_line(stderr: str) -> str:
    return [ln for ln in stderr.splitlines() if ln.strip()][-1]


@pytest.mark.parametrize("exc", [RuntimeError("SVD did not converge"), MemoryError(), OSError(28, "No space left")])
def test_an_unexpected_exception_exits_70_with_its_traceback(monkeypatch, exc):
    def broken(*_args, **_kwargs):
        raise exc

    monkeypatch.setattr("planner.collision.layout.scene_layout", broken)
    proc = lutgen_in_process("validate", SCENARIO_II)
    assert proc.returncode == ExitCode.INTERNAL == 70
    assert "Traceback (most recent call last)" in proc.stderr and "in broken" in proc.stderr
    last = _last_line(proc.stderr)
    assert last.startswith(f"internal error: {type(exc).__name__}: ")
    assert "not of the input" in last and "error: " not in last.removeprefix("internal error: ")


def test_bad_input_still_exits_1_in_one_line(monkeypatch):
    def refused(*_args, **_kwargs):
        raise LutgenError("scenario.toml: [limits] grasp_torque_max_nm must be > 0")

    monkeypatch.setattr("planner.collision.layout.scene_layout", refused)
    assert_one_line_error(lutgen_in_process("validate", SCENARIO_II), "grasp_torque_max_nm")


def test_every_command_is_guarded():
    """Each command's callback is the guard of :func:`user_errors` around the command itself."""
    guard = user_errors(lambda: None).__code__
    for name, command in main.commands.items():
        assert command.callback.__code__ is guard, name
        assert hasattr(command.callback, "__wrapped__"), name


def test_help_names_the_code():
    proc = lutgen_in_process("--help")
    assert proc.returncode == 0 and "70 internal error" in proc.stdout


def test_a_reader_that_closes_stdout_ends_the_command_quietly():
    """``lutgen inspect TABLE | head -1``: the reader goes away before lutgen writes; no traceback, exit 141."""
    import os
    import subprocess

    from tests.support.cli import LUTGEN

    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line: every write meets a closed pipe
    proc = subprocess.run([LUTGEN, "inspect", str(ROOT / "tests" / "data" / "ci_golden.h5")], stdout=write_end,
                          stderr=subprocess.PIPE, text=True, timeout=120)
    os.close(write_end)
    assert proc.returncode == ExitCode.READER_GONE == 141, proc.stderr
    assert proc.stderr == ""


def test_a_broken_pipe_that_is_not_stdouts_is_an_internal_error(monkeypatch):
    def broken(*_args, **_kwargs):
        raise BrokenPipeError(32, "Broken pipe")  # a worker's pipe, say: stdout is still read

    monkeypatch.setattr("planner.collision.layout.scene_layout", broken)
    proc = lutgen_in_process("validate", SCENARIO_II)
    assert proc.returncode == ExitCode.INTERNAL
    assert _last_line(proc.stderr).startswith("internal error: BrokenPipeError: ")
