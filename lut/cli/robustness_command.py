"""``lutgen robustness``: how much observation error a plan absorbs (success probability, failures, error scale).

Exit code 0 when the report was produced and, with ``--min-success P``, the Wilson 95 % lower bound of the
success probability at scale 1 is ≥ P; 2 when it is below P (no-go); 1 for bad input.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from lut.cli.exit_codes import ExitCode
from lut.cli.user_errors import user_errors, write_error
from planner.errors import LutgenError

if TYPE_CHECKING:  # imported lazily at run time: `lutgen --help` must not load the planner
    from lut.robustness.analysis import RobustnessRequest
    from lut.robustness.error_model import ErrorModel
    from lut.robustness.report import RobustnessReport


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("--attitude-sigma-deg", type=float, default=0.0, show_default=True,
              help="1-σ attitude error per target body axis (deg), a small rotation composed with the observed "
                   "attitude.")
@click.option("--rate-sigma-deg-s", type=float, default=0.0, show_default=True,
              help="1-σ body-rate error per body axis (deg/s), added to the observed ω_body.")
@click.option("--covariance", "covariance_path", type=click.Path(dir_okay=False), default=None,
              help="Instead of the σ's: a text file of 6 rows of 6 numbers, the covariance of [δθ (rad); δω (rad/s)] "
                   "in the target body frame.")
@click.option("--samples", type=int, default=200, show_default=True, help="Runs at the given error (scale 1).")
@click.option("--scales", default="0,0.5,1,2", show_default=True,
              help="Error scales of the sweep (factors on both σ's); 1 is always run with --samples runs.")
@click.option("--sweep-samples", type=int, default=50, show_default=True,
              help="Runs at each sweep scale other than 1 (the first of the same draws).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the draws: same seed, same figures.")
@click.option("--step-s", type=float, default=0.02, show_default=True, help="Verification step of every run (s).")
@click.option("-j", "--jobs", type=int, default=1, show_default=True, help="Worker processes (loky).")
@click.option("--min-success", type=float, default=None,
              help="Go/no-go: exit 2 unless the 95 % lower bound of the success probability is >= this.")
@click.option("--scenario", "scenario_path", type=click.Path(dir_okay=False), default=None,
              help="Scenario file, if it moved since the plan was made (its model must be the plan's).")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Write success_vs_scale.png and worst_run_distance.png to DIR.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="Write the figures as lutgen.robustness/1 JSON here.")
@click.option("--resolve-stabilization", is_flag=True,
              help="In each run, solve the stabilization NLP warm from the plan's spline at the run's grasp state "
                   "(as the flight software would once grasped), within the planner's stabilization budget of IPOPT "
                   "iterations; where it fails, the planned spline is flown.")
@click.option("--no-progress", is_flag=True, help="No progress bar on stderr.")
@user_errors
def robustness(plan_path: str, attitude_sigma_deg: float, rate_sigma_deg_s: float, covariance_path: str | None,
               samples: int, scales: str, sweep_samples: int, seed: int, step_s: float, jobs: int,
               min_success: float | None, scenario_path: str | None, plot_dir: str | None, json_path: str | None,
               resolve_stabilization: bool, no_progress: bool) -> None:
    """Execute the plan PLAN_PATH against true target states drawn around its observed state, verify every
    run densely, and report the success probability (Wilson 95 % interval), which check fails first and how
    often, and the largest error scale at which at least 95 % of runs succeed.

    A run flies the approach as planned, the tracking IK closes on the true target's grasp frame and the
    stabilization spline is applied from the grasp state reached (or, with --resolve-stabilization, re-solved
    warm there). Exit 0: report produced (and, with --min-success, go); 2: no-go; 1: bad input.
    """
    from lut.output.paths import Output, check_outputs
    from lut.output.plan_file import load_plan
    from lut.output.plan_replay import replay_inputs, resolve_scenario
    from lut.robustness.analysis import RobustnessRequest
    from lut.robustness.sweep import parse_scales
    from planner.plan_grasps import STABILIZATION_BUDGET

    model = _error_model(attitude_sigma_deg, rate_sigma_deg_s, covariance_path)
    _check_counts(samples, sweep_samples, jobs, step_s, min_success)
    doc = load_plan(plan_path)
    inputs = replay_inputs(doc, plan_path)
    scenario = resolve_scenario(inputs, plan_path, scenario_path)
    if json_path is not None:  # before hours of runs: never over an input, never into a missing folder
        check_outputs([plan_path, scenario.source], [Output("--json", Path(json_path))])
    request = RobustnessRequest(scenario.source, inputs.state, inputs.parameters, model, samples, seed,
                                tuple(parse_scales(scales)), sweep_samples, step_s, jobs,
                                STABILIZATION_BUDGET if resolve_stabilization else None)
    report = _run_with_progress(request, no_progress)
    for line in report.lines():
        click.echo(line)
    _write_outputs(report, doc, scenario.limits.collision_margin_m, plot_dir, json_path)
    if min_success is not None and report.success.low < min_success:
        click.echo(f"NO-GO: the success probability's 95 % lower bound {report.success.low:.3f} < {min_success:g}",
                   err=True)
        raise SystemExit(ExitCode.INFEASIBLE)


def _error_model(attitude_sigma_deg: float, rate_sigma_deg_s: float, covariance_path: str | None) -> ErrorModel:
    """The error model of the options: the covariance file, or the two σ's (not both)."""
    from lut.robustness.error_model import ErrorModel

    if covariance_path is not None:
        if attitude_sigma_deg or rate_sigma_deg_s:
            raise LutgenError("--covariance: give either the covariance file or the σ's, not both")
        return ErrorModel.from_file(covariance_path)
    for option, value in (("--attitude-sigma-deg", attitude_sigma_deg), ("--rate-sigma-deg-s", rate_sigma_deg_s)):
        if not math.isfinite(value) or value < 0:
            raise LutgenError(f"{option}: must be a finite number >= 0, got {value}")
    return ErrorModel.from_sigmas(math.radians(attitude_sigma_deg), math.radians(rate_sigma_deg_s))


def _check_counts(samples: int, sweep_samples: int, jobs: int, step_s: float, min_success: float | None) -> None:
    """Refuse counts < 1, a verification step outside (0, 0.02] s and a threshold outside [0, 1]."""
    for option, value in (("--samples", samples), ("--sweep-samples", sweep_samples), ("--jobs", jobs)):
        if value < 1:
            raise LutgenError(f"{option}: must be >= 1, got {value}")
    if not 0 < step_s <= 0.02:
        raise LutgenError(f"--step-s: must be in (0, 0.02] s, got {step_s}")
    if min_success is not None and not 0 <= min_success <= 1:
        raise LutgenError(f"--min-success: must be in [0, 1], got {min_success}")


def _run_with_progress(request: RobustnessRequest, no_progress: bool) -> RobustnessReport:
    """The analysis with a progress bar over its runs on stderr (none with --no-progress)."""
    import sys

    from lut.robustness.analysis import analyse

    total = sum(request.samples if s == 1.0 else min(request.sweep_samples, request.samples) for s in request.scales)
    if no_progress:
        return analyse(request)
    from tqdm import tqdm

    with tqdm(total=total, unit="run", desc="robustness", dynamic_ncols=True, file=sys.stderr) as bar:
        return analyse(request, bar.update)


def _write_outputs(report: RobustnessReport, doc: dict[str, Any], margin_m: float, plot_dir: str | None,
                   json_path: str | None) -> None:
    """The figures to ``plot_dir`` and the JSON document to ``json_path``, where asked."""
    if json_path is not None:
        from lut.output.export import write_json

        write_json(json_path, report.document())
        click.echo(f"wrote {json_path}")
    if plot_dir is not None:
        from lut.output.plan_file import phase_spans
        from lut.output.robustness_plots import write_robustness_plots

        try:
            for path in write_robustness_plots(report, phase_spans(doc), margin_m, plot_dir):
                click.echo(f"wrote {path}")
        except OSError as exc:
            raise write_error(plot_dir, exc) from None


COMMANDS = (robustness,)
