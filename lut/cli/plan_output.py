"""How ``lutgen plan`` and ``lutgen query`` end: the plan summary printed, the plan files written, the verdict."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NoReturn

import click

from lut.cli.answer_time import AnswerTime
from lut.cli.exit_codes import ExitCode
from lut.cli.process_end import end_command, exit_now

if TYPE_CHECKING:  # imported lazily at run time: `lutgen --help` must not load the planner
    from lut.table.plan_costs import CostBreakdown, CostScorer
    from planner.plan import GraspPlan
    from planner.verify.verifier import VerifyReport


SOLVE_NOTE_PREFIX = "note: the solve: "  # a query's or re-plan's line for a note of the solve that made its plan


def plan_table(result: GraspPlan, report: VerifyReport) -> list[str]:
    """The summary lines of a plan and its verification (times [s], offsets [m], torques [N·m])."""
    import numpy as np

    a, s = result.approach, result.stabilization
    lines = ["phase          start [s]   end [s]   solver                 iters   time [s]"]
    # phase times from the plan's timings where it has them: they include every grasp a plan tried
    t = result.timings_s
    solver = {"approach": (a.status, a.iterations, t.get("approach_s") or a.solve_time_s),
              "tracking": ("IK (Eq. 7)", "-", t.get("tracking_s", 0.0)),
              "stabilization": (s.status, s.iterations, t.get("stabilization_s") or s.solve_time_s + s.build_time_s)}
    for name, (t0, t1) in result.phases.items():
        st, it, tm = solver[name]
        lines.append(f"{name:<14} {t0:9.2f} {t1:9.2f}   {st:<22} {it!s:>5} {tm:9.2f}")
    lines.append(f"start delay {a.start_delay_s:.2f} s, base offset θ_b(0) = ({a.base_offset_m[0]:+.4f}, "
                 f"{a.base_offset_m[1]:+.4f}) m (x, z), total planning time {result.timings_s['total_s']:.1f} s")
    lines.append(f"min distance {np.min(report.min_distance_m):.4f} m over {report.pair_count} pairs; "
                 f"peak grasp torque {np.abs(report.grasp_wrench[:, 3:]).max():.3f} N·m")
    return lines


def plan_lines(result: GraspPlan, report: VerifyReport, notes: tuple[str, ...] | list[str] = (),
               note_prefix: str = "note: ") -> list[str]:
    """What every command that answers with a plan prints: :func:`plan_table`, each of ``notes`` as one line after
    ``note_prefix``, what the verdict adds (:func:`lut.output.export.verdict_notes`), then the verification's
    summary."""
    from lut.output.export import verdict_notes
    from planner.verify.verifier import summary_lines

    return [*plan_table(result, report), *(note_prefix + note for note in notes),
            *("note: " + note for note in verdict_notes(result, report)), *summary_lines(report)]


def cost_table(costs: tuple[CostBreakdown, ...], scorer: CostScorer, source: str) -> list[str]:
    """The query's plan's weighted cost terms next to its corners' (one row each), or one line saying the table
    holds feasible plans only (every weight 0)."""
    if scorer.feasibility_only or not costs:
        return ["cost: none — the scenario weights no cost term (a feasibility-only table), so there is no "
                "optimum to compare"]
    terms = costs[0].terms
    title = "cost (" + " ".join(f"{'−' if t.sign < 0 else '+'}{t.weight:g}·{t.name}" for t in terms) + ")"
    labels = [f"plan ({source})" if row.label == "plan" else row.label for row in costs]
    width = max(len(text) for text in [title, *labels]) + 2
    lines = [f"{title:<{width}}" + "".join(f"{t.name + (f' [{t.unit}]' if t.unit else ''):>24}" for t in terms)
             + f"{'total':>14}"]
    for label, row in zip(labels, costs, strict=True):
        lines.append(f"{label:<{width}}" + "".join(f"{t.value:>24.6g}" for t in row.terms) + f"{row.total:>14.6g}")
    if scorer.unscored_weights:
        lines.append("cost: the stabilization terms " + ", ".join(scorer.unscored_weights) + " are weighted but not "
                     "compared here")
    return lines


def query_block(costs: tuple[CostBreakdown, ...], scorer: CostScorer, source: str,
                corners: list[int]) -> dict[str, Any]:
    """The ``query`` object a query adds to its plan file: source, corners, and the cost rows of :func:`cost_table`."""
    return {"source": source, "corners": list(corners), "feasibility_only": scorer.feasibility_only,
            "cost_weights": {t.name: t.weight for t in costs[0].terms} if costs else {},
            "costs": [row.as_dict() for row in costs]}


def export_and_verdict(result: GraspPlan, report: VerifyReport, out_path: str | None, csv_path: str | None,
                       started_s: float | None, extra: dict[str, Any] | None = None) -> None:
    """Write the plan JSON (with ``extra``'s top-level keys and the ``answer`` object) and CSV where asked, then
    print FEASIBLE, or the violations (and lateness) and exit 2. ``started_s``: the command's start, on
    ``time.monotonic()``'s clock, taken as the observation's instant (None: an offline plan, whose start is not
    judged against its answer)."""
    import time

    from lut.output.export import plan_document, write_csv, write_json

    answer = None if started_s is None else AnswerTime(result.approach.start_delay_s, time.monotonic() - started_s)
    timing = {} if answer is None else {"answer": answer.as_dict()}
    if out_path:
        write_json(out_path, plan_document(result, report) | (extra or {}) | timing)
        click.echo(f"wrote {out_path}")
    if csv_path:
        write_csv(csv_path, result, report)
        click.echo(f"wrote {csv_path}")
    if answer is not None:
        click.echo(answer.line())
    refusals = [*report.violations, *([answer.reason()] if answer is not None and answer.late else [])]
    if refusals:
        click.echo("INFEASIBLE: " + "; ".join(refusals), err=True)
        exit_now(ExitCode.INFEASIBLE)
    click.echo("FEASIBLE")
    end_command(ExitCode.OK)


def refuse_without_plan(reason: Exception, elapsed_s: float, out_path: str | None, csv_path: str | None) -> NoReturn:
    """No trajectory was made (out of reach, or no time to solve): say why in one line and exit 2, writing nothing."""
    click.echo(f"INFEASIBLE ({elapsed_s:.1f} s): {reason}", err=True)
    if out_path or csv_path:
        click.echo("no plan written: there is no trajectory to export", err=True)
    exit_now(ExitCode.INFEASIBLE)
