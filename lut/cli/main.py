"""The ``lutgen`` command line: the group that assembles every command, its exit codes and one-line warnings.

Errors a user can cause (bad config, option value, file, target state) are printed as one line
``error: …`` on stderr with exit code 1, never a traceback (:mod:`lut.cli.user_errors`); a malformed
command line (click's usage errors) exits 64; plan and query exit 2 for an infeasible plan
(:class:`lut.cli.exit_codes.ExitCode`); any other exception is lutgen's own failure: its traceback, a last line
``internal error: …`` and exit code 70, never 1. Warnings (e.g. compiled Functions falling back to interpreted
ones, :mod:`planner.nlp.compiled`) are one line ``warning: …`` too. The commands live in
:mod:`lut.cli.plan_commands`, :mod:`lut.cli.table_commands` and :mod:`lut.cli.view`; each imports the
planner only when it runs, so ``lutgen --help`` is fast.
"""

from __future__ import annotations

import warnings
from typing import Any

import click

from lut.cli import plan_commands, process_end, replan_command, robustness_command, table_commands, view
from lut.cli.exit_codes import ExitCode


class LutgenGroup(click.Group):
    """The ``lutgen`` group: a malformed command line exits :attr:`ExitCode.USAGE`, never 2 (= infeasible)."""

    def make_context(self, *args: Any, **kwargs: Any) -> click.Context:
        try:
            return super().make_context(*args, **kwargs)
        except click.UsageError as exc:
            exc.exit_code = ExitCode.USAGE
            raise

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            exc.exit_code = ExitCode.USAGE
            raise


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                      line: str | None = None) -> str:
    return f"warning: {message}\n"


@click.group(cls=LutgenGroup)
@click.version_option(package_name="lutgen")
def main() -> None:
    """lutgen: plan grasps of a tumbling satellite with a free-floating 7-DOF arm.

    \b
    Workflows:
      lutgen validate SCENARIO.toml               check a scenario, its robot URDF and its target
      lutgen plan SCENARIO.toml --out plan.json   plan one grasp directly (no table)
      lutgen build GRID.toml --out TABLE.h5 -j 8  build a look-up table (journaled; --resume after a crash)
      lutgen inspect TABLE.h5 [--plot DIR]        counts, statistics and coverage maps of a table
      lutgen query TABLE.h5 --attitude W,X,Y,Z --omega-deg-s X,Y,Z --out plan.json
                                                  observed state → verified plan from the table
      lutgen plot plan.json -o DIR                figures of a plan (PNG)
      lutgen preview plan.json -o preview.html    3D animation of a plan (one HTML page)
      lutgen robustness plan.json --attitude-sigma-deg 0.5 --rate-sigma-deg-s 0.05 -j 2
                                                  how much observation error the plan absorbs
      lutgen replan plan.json --attitude W,X,Y,Z --omega-deg-s X,Y,Z --since-s T --out new.json
                                                  a newer estimate before the approach starts → continuous plan

    \b
    Exit codes: 0 done (plan/query: feasible), 1 bad input (one line "error: …"),
    2 infeasible (plan/query) or no-go (robustness --min-success), 64 malformed command line,
    70 internal error (a defect or the machine; the traceback and a last line "internal error: …"),
    141 stdout's reader closed it (e.g. "| head"; quietly).
    """
    warnings.formatwarning = _one_line_warning


for _command in (*plan_commands.COMMANDS, *table_commands.COMMANDS, *robustness_command.COMMANDS,
                 *replan_command.COMMANDS, *view.COMMANDS):
    main.add_command(_command)


def run() -> None:
    """The ``lutgen`` console script: :func:`main` in a process of its own, which a command that has flushed its
    answer ends at once (:mod:`lut.cli.process_end`)."""
    process_end.END_AT_ONCE = True
    main()


if __name__ == "__main__":
    run()
