"""A command that has given its answer ends: in the console script at once (flushed, no teardown), in-process as
before (exit code 0 returns, any other raises SystemExit)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from lut.cli import process_end
from lut.cli.exit_codes import ExitCode


class _Ended(Exception):
    pass


def test_in_process_a_zero_code_returns_and_another_exits(monkeypatch):
    monkeypatch.setattr(process_end, "END_AT_ONCE", False)
    monkeypatch.setattr(process_end.os, "_exit", lambda code: pytest.fail("in-process must never end the process"))
    assert process_end.end_command(ExitCode.OK) is None
    with pytest.raises(SystemExit) as ended:
        process_end.end_command(ExitCode.INFEASIBLE)
    assert ended.value.code == ExitCode.INFEASIBLE


@pytest.mark.parametrize("code", [ExitCode.OK, ExitCode.INFEASIBLE])
def test_the_console_script_ends_at_once_with_the_code(monkeypatch, code):
    def os_exit(value):
        raise _Ended(value)

    monkeypatch.setattr(process_end, "END_AT_ONCE", True)
    monkeypatch.setattr(process_end.os, "_exit", os_exit)
    with pytest.raises(_Ended) as ended:
        process_end.end_command(code)
    assert ended.value.args == (int(code),)


def test_a_process_ended_at_once_has_written_everything(tmp_path):
    """Output still buffered in Python's streams (a pipe is block-buffered) reaches the reader."""
    script = ("import sys; from lut.cli import process_end; from lut.cli.exit_codes import ExitCode; "
              "process_end.END_AT_ONCE = True; print('x' * 100000); print('FEASIBLE'); "
              "print('INFEASIBLE: none', file=sys.stderr); process_end.end_command(ExitCode.INFEASIBLE); "
              "print('not reached')")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == ExitCode.INFEASIBLE
    assert proc.stdout.splitlines()[-1] == "FEASIBLE" and len(proc.stdout) == 100000 + len("\nFEASIBLE\n")
    assert proc.stderr == "INFEASIBLE: none\n"
