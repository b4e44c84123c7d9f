"""Figures of a plan (``lut.output.plots``), coverage maps of a table (``lut.output.coverage_plots``), ``lutgen plot``.

The plans are real ones of both paper scenarios (``tests/data/plan_*.json.gz``: ``lutgen plan`` output
thinned to 0.1 s by ``scripts/make_plan_testdata.py``, every field kept). A figure passes when its PNG
exists, is not blank (pixel spread) and carries the expected title in its ``Title`` metadata.
"""

from __future__ import annotations

import copy
import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lut.output.plan_file import PlanFileError, check_plan, load_plan
from lut.output.plots import TITLES, write_plots

DATA = Path(__file__).resolve().parents[2] / "data"
ROOT = Path(__file__).resolve().parents[3]
PLANS = ("plan_I", "plan_II")


@pytest.fixture(scope="module", params=PLANS)
def plan(request) -> dict:
    return load_plan(DATA / f"{request.param}.json.gz")


def png_title(path: Path) -> str:
    with Image.open(path) as img:
        return img.text.get("Title", "")


def assert_not_blank(path: Path) -> None:
    with Image.open(path) as img:
        pixels = np.asarray(img.convert("L"), dtype=float)
    assert pixels.shape[0] > 200 and pixels.shape[1] > 200, pixels.shape
    assert pixels.std() > 10, f"{path.name} looks blank (pixel std {pixels.std():.1f})"


def test_write_plots_renders_every_figure(plan, tmp_path):
    paths = write_plots(plan, tmp_path / "figs")
    assert [p.name for p in paths] == [f"{name}.png" for name in TITLES]
    for path, (name, title) in zip(paths, TITLES.items(), strict=True):
        assert path.is_file()
        assert_not_blank(path)
        got = png_title(path)
        assert got.startswith(f"{title} — {plan['scenario']}, {plan['status']}"), (name, got)
        assert "not found" not in got and "not in plan file" not in got, got  # the data has everything


def _save(make, doc: dict, path: Path) -> Path:
    from lut.output.plot_style import save_figure

    fig, title = make(doc)
    return save_figure(fig, path, title)


def test_plots_say_what_is_missing(tmp_path):
    """A plan from an older export (no distances) and one whose robot URDF is gone still plot, and say so."""
    from lut.output.plots import collision_distance_figure, joints_figure

    doc = load_plan(DATA / "plan_II.json.gz")
    for key in ("min_distance_m", "closest_pair", "closest_points_m"):
        doc["samples"].pop(key)
    doc["robot_urdf"] = "no/such/robot.urdf"
    collision = _save(collision_distance_figure, doc, tmp_path / "c.png")
    joints = _save(joints_figure, doc, tmp_path / "j.png")
    assert png_title(collision).endswith("(not in plan file)")
    assert "'no/such/robot.urdf' not found: no limit lines" in png_title(joints)
    for path in (collision, joints):
        assert_not_blank(path)


def test_unconstrained_wrench_limits_plot(tmp_path):
    from lut.output.plots import grasp_wrench_figure

    doc = load_plan(DATA / "plan_II.json.gz")
    doc["metrics"]["limits"]["grasp_torque_max_nm"] = None
    path = _save(grasp_wrench_figure, doc, tmp_path / "w.png")
    assert png_title(path).startswith(TITLES["grasp_wrench"])
    assert_not_blank(path)


def test_reader_schema_matches_the_writer():
    from lut.output.export import SCHEMA
    from lut.output.plan_file import SCHEMA as READ

    assert READ == SCHEMA


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d.update(schema="lutgen.plan/0"), r"schema: expected 'lutgen.plan/1', got 'lutgen.plan/0'"),
    (lambda d: d["samples"]["q"].pop(), r"samples.q: \d+ rows, samples.t has \d+"),
    (lambda d: d["samples"].pop("base_wxyz"), r"samples.base_wxyz: missing"),
    (lambda d: d["phases"].pop("tracking"), r"phases: expected approach, tracking, stabilization"),
    (lambda d: d["samples"]["t"].reverse(), r"samples.t: must be strictly increasing"),
    (lambda d: d["samples"]["closest_pair"].pop(), r"samples.closest_pair: expected shape"),
    (lambda d: d["target"]["shapes"][1].pop("radius_m"), r"target.shapes\[1\]: a capsule needs radius_m > 0"),
    (lambda d: d["target"]["shapes"][0].update(kind="sphere"), r"target.shapes\[0\]: expected an object with kind"),
])
def test_check_plan_names_the_field(mutate, match):
    doc = copy.deepcopy(load_plan(DATA / "plan_II.json.gz"))
    mutate(doc)
    with pytest.raises(PlanFileError, match=match):
        check_plan(doc, "p.json")


def test_load_plan_rejects_missing_and_non_json(tmp_path):
    with pytest.raises(PlanFileError, match="no such plan file"):
        load_plan(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(PlanFileError, match="bad.json: not a plan JSON file"):
        load_plan(tmp_path / "bad.json")
    (tmp_path / "bad.json.gz").write_bytes(gzip.compress(b"\xff\xfe"))
    with pytest.raises(PlanFileError, match="not a plan JSON file"):
        load_plan(tmp_path / "bad.json.gz")


# ---- coverage maps -------------------------------------------------------------------------------


def _table(path: Path, axes: list[tuple[str, np.ndarray]], torque: bool = True):
    from lut.table.model_identity import model_hash
    from lut.table.store import Table
    from lut.table.table_writer import write_table

    n = int(np.prod([len(v) for _, v in axes]))
    rng = np.random.default_rng(1)
    records = {}
    for p in range(n):
        if p % 7 == 3:
            continue  # pending
        status = ("feasible", "infeasible", "failed")[p % 3]
        rec = {"point": p, "status": status, "solve_time_s": float(20 + 80 * rng.random()), "iterations": 5}
        if status != "failed":
            rec["costs/min_distance_m"] = float(0.02 + 0.1 * rng.random())
            if torque:
                rec["costs/peak_grasp_torque_nm"] = float(10 * rng.random())
        records[p] = rec
    write_table(path, grid_axes=axes, grid_kind="flat_spin", config_text="", scenario_text="",
                model_hash=model_hash("r", "t", "s"), records=records, n_points=n)
    return Table.open(path)


RATE = ("spin_rate_deg_s", np.array([3.0, 3.5, 4.0]))
ANGLE = ("spin_axis_angle_deg", np.array([80.0, 90.0]))
ANGLE_FIXED = ("spin_axis_angle_deg", np.array([90.0]))
PHASE = ("spin_phase_deg", np.array([0.0, 10.0, 20.0, 30.0]))
PHASE_FIXED = ("spin_phase_deg", np.array([0.0]))


@pytest.mark.parametrize("axes, fixed", [
    ([RATE, ANGLE_FIXED, PHASE_FIXED], "fixed spin_axis_angle_deg = 90, spin_phase_deg = 0"),  # 1 varying: lines
    ([RATE, ANGLE_FIXED, PHASE], "fixed spin_axis_angle_deg = 90"),  # 2 varying: heatmap
    ([RATE, ANGLE, PHASE], ""),  # 3 varying: small multiples
])
def test_coverage_maps_for_1_2_3_varying_axes(tmp_path, axes, fixed):
    from lut.output.coverage_plots import write_coverage_maps

    table = _table(tmp_path / "t.h5", axes)
    paths = write_coverage_maps(table, tmp_path / "maps")
    assert [p.name for p in paths] == ["coverage_status.png", "coverage_min_distance_m.png",
                                       "coverage_peak_grasp_torque_nm.png", "coverage_solve_time_s.png"]
    for path, label in zip(paths, ("point status", "min collision distance [m]", "peak grasp torque [N·m]",
                                   "solve time [s]"), strict=True):
        assert_not_blank(path)
        title = png_title(path)
        assert title.startswith(f"Coverage: {label} — t.h5 ({table.n_points} points"), title
        assert fixed in title


def test_coverage_maps_skip_missing_costs_and_page_many_panels(tmp_path, monkeypatch):
    import lut.output.coverage_plots as cp

    # heatmaps omega_z × omega_y; panels: omega_x (rows) × pitch (columns) = 4, two per page
    monkeypatch.setattr(cp, "MAX_PANELS", 2)
    monkeypatch.setattr(cp, "MAX_COLUMNS", 2)
    axes = [("omega_x_deg_s", np.array([-1.0, 1.0])), ("omega_y_deg_s", np.array([-1.0, 0.0, 1.0])),
            ("omega_z_deg_s", np.array([-2.0, 0.0, 2.0])), ("roll_deg", np.array([0.0])),
            ("pitch_deg", np.array([-10.0, 10.0])), ("yaw_deg", np.array([0.0]))]
    table = _table(tmp_path / "tumble.h5", axes, torque=False)
    paths = cp.write_coverage_maps(table, tmp_path)
    assert [p.name for p in paths] == ["coverage_status.png", "coverage_status_2.png", "coverage_min_distance_m.png",
                                       "coverage_min_distance_m_2.png", "coverage_solve_time_s.png",
                                       "coverage_solve_time_s_2.png"]  # no peak torque in this table
    assert png_title(tmp_path / "coverage_status_2.png").endswith("fixed roll_deg = 0, yaw_deg = 0) [page 2/2]")
    for path in paths:
        assert_not_blank(path)


# ---- CLI -----------------------------------------------------------------------------------------

# the view commands on the real main group, as lut/cli/main.py wires them
CLI = "from lut.cli.main import main; main()"


def _run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CLI, *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_cli_plot_writes_and_lists_the_figures(tmp_path):
    out = tmp_path / "figs"
    res = _run("plot", str(DATA / "plan_II.json.gz"), "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [f"wrote {out / name}.png" for name in TITLES]


def test_cli_preview_writes_the_page(tmp_path):
    out = tmp_path / "p" / "preview.html"
    res = _run("preview", str(DATA / "plan_I.json.gz"), "-o", str(out), "--max-frames", "20")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == f"wrote {out}" and out.stat().st_size > 1_000_000


def _cli_in_process(*args: str):
    """The view commands on a fresh click group, in this process (fast), stderr kept apart."""
    import click
    from click.testing import CliRunner

    from lut.cli.view import COMMANDS

    group = click.Group()
    for command in COMMANDS:
        group.add_command(command)
    return CliRunner().invoke(group, list(args))


@pytest.mark.parametrize("command", ["plot", "preview"])
@pytest.mark.parametrize("content, message", [
    (None, "error: {p}: no such plan file"),
    ("[1, 2", "error: {p}: not a plan JSON file"),
    (json.dumps({"schema": "other"}), "error: {p}: schema: expected 'lutgen.plan/1', got 'other'"),
])
def test_cli_bad_plan_is_one_line_exit_1(tmp_path, command, content, message):
    path = tmp_path / "plan.json"
    if content is not None:
        path.write_text(content, encoding="utf-8")
    res = _cli_in_process(command, str(path), "-o", str(tmp_path / "out"))
    assert res.exit_code == 1 and isinstance(res.exception, SystemExit), res.exception  # not a crash
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message.format(p=path)), res.stderr
    assert res.stdout == ""


def test_cli_bad_plan_in_a_real_process_has_no_traceback(tmp_path):
    path = tmp_path / "plan.json"
    path.write_text("not json", encoding="utf-8")
    res = _run("preview", str(path))
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert res.stderr.strip().splitlines() == [f"error: {path}: not a plan JSON file "
                                               "(Expecting value: line 1 column 1 (char 0))"]


def test_cli_unwritable_output_is_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x", encoding="utf-8")
    res = _cli_in_process("preview", str(DATA / "plan_II.json.gz"), "-o", str(blocker / "p.html"),
                          "--max-frames", "5")
    assert res.exit_code == 1 and isinstance(res.exception, SystemExit), res.exception
    assert res.stderr.strip().splitlines() == [f"error: {blocker / 'p.html'}: cannot write (File exists: {blocker})"]


def test_lutgen_main_has_the_view_commands():
    """lut/cli/main.py assembles plot and preview into the group with the other commands."""
    from lut.cli.main import main

    assert {"plot", "preview"} <= set(main.commands)
