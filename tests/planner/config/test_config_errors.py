"""``lutgen validate`` on broken configs: one line ``error: <file>: <field>: <problem>``, exit code 1.

Each case copies the bundled configs (scenarios, targets, robot URDF, same relative layout) into a
temporary folder, applies ONE mutation, and runs the installed ``lutgen`` console script as a real
subprocess, so the whole path (TOML/URDF loaders, CLI error handling, process exit) is exercised.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
CONFIGS = ROOT / "configs"

SCEN_I = "scenarios/scenario_I.toml"
SCEN_II = "scenarios/scenario_II.toml"
TARGET_I = "targets/scenario_I_target.toml"
TARGET_II = "targets/scenario_II_target.toml"
URDF = "robots/chaser7.urdf"


def _lutgen() -> str:
    exe = Path(sys.executable).parent / "lutgen"
    if exe.is_file():
        return str(exe)
    found = shutil.which("lutgen")
    if found is None:
        pytest.skip("the lutgen console script is not installed (pip install -e .)")
    return found


def _copy_configs(dest: Path) -> Path:
    """Copy the bundled scenario, target and robot files into ``dest/configs`` (same relative layout)."""
    root = dest / "configs"
    for sub in ("scenarios", "targets", "robots"):
        shutil.copytree(CONFIGS / sub, root / sub)
    return root


def _run(scenario: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([_lutgen(), "validate", str(scenario)], capture_output=True, text=True,
                          timeout=60, cwd=scenario.parent)


# ----------------------------------------------------------------------------------------------------
# Mutations: each edits exactly one thing and checks that the text it edits is really there, so a
# change of the bundled configs makes the test fail loudly instead of testing nothing.

Mutation = Callable[[Path], None]


_HEADER = re.compile(r"^\s*\[+\s*([^\]]+?)\s*\]+")


def set_key(rel: str, table: str, key: str, value: str) -> Mutation:
    """Set ``key = value`` in TOML table ``table`` ("" = top level); the key must already be there once.

    Values already in the file do not matter, so the bundled configs may be retuned freely.
    """

    def apply(root: Path) -> None:
        path = root / rel
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        current, hits = "", []
        for i, line in enumerate(lines):
            header = _HEADER.match(line)
            if header:
                current = header.group(1)
            elif current == table and re.match(rf"\s*{re.escape(key)}\s*=", line):
                hits.append(i)
        assert len(hits) == 1, f"{rel}: expected one {key!r} in [{table}], found {len(hits)}"
        lines[hits[0]] = f"{key} = {value}\n"
        path.write_text("".join(lines), encoding="utf-8")

    return apply


def replace(rel: str, old: str, new: str) -> Mutation:
    """Replace the single line matching regex ``old`` (anchored at line start) with ``new``."""

    def apply(root: Path) -> None:
        path = root / rel
        text = path.read_text(encoding="utf-8")
        pattern = re.compile(rf"^{old}.*$", re.MULTILINE)
        assert len(pattern.findall(text)) == 1, f"{rel}: expected exactly one line matching {old!r}"
        path.write_text(pattern.sub(lambda _: new, text), encoding="utf-8")

    return apply


def replace_block(rel: str, start: str, stop: str, new: str) -> Mutation:
    """Replace everything from the line matching regex ``start`` up to (not including) the line ``stop``."""

    def apply(root: Path) -> None:
        path = root / rel
        text = path.read_text(encoding="utf-8")
        pattern = re.compile(rf"^{start}.*?(?=^{stop})", re.MULTILINE | re.DOTALL)
        assert len(pattern.findall(text)) == 1, f"{rel}: block {start!r}…{stop!r} not found"
        path.write_text(pattern.sub(lambda _: new, text), encoding="utf-8")

    return apply


def delete_line(rel: str, old: str) -> Mutation:
    def apply(root: Path) -> None:
        path = root / rel
        text = path.read_text(encoding="utf-8")
        pattern = re.compile(rf"^{old}.*\n", re.MULTILINE)
        assert len(pattern.findall(text)) == 1, f"{rel}: expected exactly one line matching {old!r}"
        path.write_text(pattern.sub("", text), encoding="utf-8")

    return apply


def append_after(rel: str, anchor: str, line: str) -> Mutation:
    """Insert ``line`` after the single line that starts with ``anchor`` (e.g. a table header)."""

    def apply(root: Path) -> None:
        path = root / rel
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        hits = [i for i, x in enumerate(lines) if x.startswith(anchor)]
        assert len(hits) == 1, f"{rel}: expected exactly one line starting with {anchor!r}"
        lines.insert(hits[0] + 1, line + "\n")
        path.write_text("".join(lines), encoding="utf-8")

    return apply


def append(rel: str, text: str) -> Mutation:
    def apply(root: Path) -> None:
        path = root / rel
        path.write_text(path.read_text(encoding="utf-8") + "\n" + text + "\n", encoding="utf-8")

    return apply


def write(rel: str, content: str | bytes) -> Mutation:
    def apply(root: Path) -> None:
        path = root / rel
        assert path.is_file(), rel
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")

    return apply


def remove(rel: str) -> Mutation:
    def apply(root: Path) -> None:
        (root / rel).unlink()

    return apply


def urdf_joint3_limit(lower: str, upper: str) -> Mutation:
    def apply(root: Path) -> None:
        path = root / URDF
        text = path.read_text(encoding="utf-8")
        pattern = re.compile(r'(<joint name="joint3".*?<limit )lower="[^"]*" upper="[^"]*"', re.DOTALL)
        new, n = pattern.subn(rf'\g<1>lower="{lower}" upper="{upper}"', text)
        assert n == 1, "chaser7.urdf: joint3 <limit> not found"
        path.write_text(new, encoding="utf-8")

    return apply


# ----------------------------------------------------------------------------------------------------
# Cases


@dataclass(frozen=True)
class Case:
    id: str
    mutation: Mutation
    file: str  # basename the message must name
    field: str | None  # dotted field the message must name (None: the whole file is bad)
    problem: str  # substring of the problem text (case-insensitive)
    scenario: str = SCEN_I


CASES = [
    # unknown fields
    Case("scenario-unknown-top", append_after(SCEN_I, "name = ", "colour = 'red'"),
         "scenario_I.toml", "colour", "unknown field"),
    Case("scenario-unknown-in-table", append_after(SCEN_I, "[phases]", "approch_s = 1"),
         "scenario_I.toml", "phases.approch_s", "unknown field"),
    Case("scenario-unknown-table", append(SCEN_I, "[phase]\napproach_s = 1"),
         "scenario_I.toml", "phase", "unknown field"),
    Case("target-unknown-top", append_after(TARGET_I, "mass_kg", "mass_lb = 2200.0"),
         "scenario_I_target.toml", "mass_lb", "unknown field"),
    Case("target-unknown-in-shape", append_after(TARGET_I, 'kind = "capsule"', "colour = 'red'"),
         "scenario_I_target.toml", "shapes[1].colour", "unknown field"),
    Case("target-unknown-in-grasp", append_after(TARGET_I, "[grasp]", "force_n = 3"),
         "scenario_I_target.toml", "grasp.force_n", "unknown field"),
    # missing required fields
    Case("scenario-missing-phase", delete_line(SCEN_I, "approach_s ="),
         "scenario_I.toml", "phases.approach_s", "missing"),
    Case("scenario-missing-urdf", delete_line(SCEN_I, "robot_urdf ="),
         "scenario_I.toml", "robot_urdf", "missing"),
    Case("scenario-missing-table", delete_line(SCEN_I, r"\[target_state\]"),  # its keys become top-level
         "scenario_I.toml", "target_state", "missing"),
    Case("target-missing-mass", delete_line(TARGET_I, "mass_kg ="),
         "scenario_I_target.toml", "mass_kg", "missing"),
    # wrong types
    Case("scenario-string-for-number", set_key(SCEN_I, "phases", "tracking_s", '"5.0"'),
         "scenario_I.toml", "phases.tracking_s", "expected a number"),
    Case("scenario-bool-for-number", set_key(SCEN_I, "solver", "max_iter", "true"),
         "scenario_I.toml", "solver.max_iter", "expected an integer"),
    Case("scenario-float-for-integer", set_key(SCEN_I, "stabilization", "rk4_steps", "90.5"),
         "scenario_I.toml", "stabilization.rk4_steps", "expected an integer"),
    Case("target-string-for-mass", set_key(TARGET_I, "", "mass_kg", '"heavy"'),
         "scenario_I_target.toml", "mass_kg", "expected a number"),
    Case("quaternion-wrong-length", set_key(SCEN_I, "target_state", "attitude_wxyz", "[1.0, 0.0, 0.0]"),
         "scenario_I.toml", "target_state.attitude_wxyz", "list of 4 numbers"),
    Case("quaternion-string-element", set_key(SCEN_I, "target_state", "attitude_wxyz", "[1.0, 0, 0, 'x']"),
         "scenario_I.toml", "target_state.attitude_wxyz", "list of 4 numbers"),
    Case("table-is-scalar", replace(SCEN_I, r"\[target_state\]", "target_state = 3\n[target_state_]"),
         "scenario_I.toml", "target_state", "expected a table"),
    Case("shapes-not-tables", replace_block(TARGET_I, r"\[\[shapes\]\]", r"\[grasp\]", "shapes = [1, 2]\n"),
         "scenario_I_target.toml", "shapes", "expected a table"),
    Case("shape-kind-unknown", replace(TARGET_I, 'kind = "box"', 'kind = "sphere"'),
         "scenario_I_target.toml", "shapes[0].kind", "must be one of"),
    Case("start-acceleration-unknown", set_key(SCEN_I, "stabilization", "start_acceleration", '"smooth"'),
         "scenario_I.toml", "stabilization.start_acceleration", "must be one of"),
    # out-of-range values
    Case("target-negative-mass", set_key(TARGET_I, "", "mass_kg", "-3.0"),
         "scenario_I_target.toml", "mass_kg", "must be > 0"),
    Case("target-zero-mass", set_key(TARGET_I, "", "mass_kg", "0"),
         "scenario_I_target.toml", "mass_kg", "must be > 0"),
    Case("target-nan-mass", set_key(TARGET_I, "", "mass_kg", "nan"),
         "scenario_I_target.toml", "mass_kg", "finite"),
    Case("phase-zero-time", set_key(SCEN_I, "phases", "approach_s", "0.0"),
         "scenario_I.toml", "phases.approach_s", "must be > 0"),
    Case("phase-negative-time", set_key(SCEN_I, "phases", "stabilization_s", "-45.0"),
         "scenario_I.toml", "phases.stabilization_s", "must be > 0"),
    Case("phase-negative-delay", set_key(SCEN_I, "phases", "max_start_delay_s", "-1"),
         "scenario_I.toml", "phases.max_start_delay_s", "must be >= 0"),
    Case("phase-negative-earliest", append_after(SCEN_I, "[phases]", "min_start_delay_s = -1"),
         "scenario_I.toml", "phases.min_start_delay_s", "must be >= 0"),
    Case("phase-earliest-after-latest", append_after(SCEN_I, "[phases]", "min_start_delay_s = 90.5"),
         "scenario_I.toml", "phases.min_start_delay_s", "must not exceed max_start_delay_s"),
    Case("too-few-vertices", set_key(SCEN_I, "approach", "n_vertices", "4"),
         "scenario_I.toml", "approach.n_vertices", "must be >= 8"),
    Case("box-size-negative", set_key(TARGET_I, "shapes", "size_m", "[1.6, -1.2, 1.6]"),
         "scenario_I_target.toml", "shapes[0].size_m", "> 0"),
    Case("grasp-axes-parallel", set_key(TARGET_I, "grasp", "reference_axis", "[2.0, 0.0, 0.0]"),
         "scenario_I_target.toml", "grasp.reference_axis", "parallel"),
    # inertia
    Case("inertia-not-positive-definite", set_key(TARGET_I, "", "inertia_kg_m2", "[100, -5, 30]"),
         "scenario_I_target.toml", "inertia_kg_m2", "positive definite"),
    Case("inertia-triangle-inequality", set_key(TARGET_I, "", "inertia_kg_m2", "[1, 1, 5]"),
         "scenario_I_target.toml", "inertia_kg_m2", "triangle inequality"),
    Case("inertia-not-symmetric",
         set_key(TARGET_I, "", "inertia_kg_m2", "[[350, 10, 0], [0, 450, 0], [0, 0, 330]]"),
         "scenario_I_target.toml", "inertia_kg_m2", "symmetric"),
    Case("inertia-ragged-matrix",
         set_key(TARGET_I, "", "inertia_kg_m2", "[[350, 0, 0], [0, 450], [0, 0, 330]]"),
         "scenario_I_target.toml", "inertia_kg_m2", "3×3 matrix"),
    Case("inertia-matrix-string-element",
         set_key(TARGET_I, "", "inertia_kg_m2", "[[350, 0, 0], [0, 'x', 0], [0, 0, 330]]"),
         "scenario_I_target.toml", "inertia_kg_m2", "3×3 matrix"),
    Case("inertia-bool-moment", set_key(TARGET_I, "", "inertia_kg_m2", "[true, 450, 330]"),
         "scenario_I_target.toml", "inertia_kg_m2", "3 principal moments"),
    Case("inertia-wrong-length", set_key(TARGET_I, "", "inertia_kg_m2", "[350, 450]"),
         "scenario_I_target.toml", "inertia_kg_m2", "3 principal moments"),
    # ranges
    Case("range-min-gt-max", set_key(SCEN_I, "robot", "base_offset_x_m", "[1.0, -1.0]"),
         "scenario_I.toml", "robot.base_offset_x_m", "min > max"),
    Case("base-guess-outside-range", set_key(SCEN_I, "robot", "base_offset_guess_m", "[2.0, 0.0]"),
         "scenario_I.toml", "robot.base_offset_guess_m", "inside"),
    # target state, initial joints
    Case("quaternion-not-unit", set_key(SCEN_I, "target_state", "attitude_wxyz", "[1.0, 0.1, 0.0, 0.0]"),
         "scenario_I.toml", "target_state.attitude_wxyz", "unit norm"),
    Case("initial-joints-outside-limits",
         set_key(SCEN_I, "robot", "initial_joints_deg", "[0.0, 45.0, 0.0, 150.0, 0.0, 45.0, 0.0]"),
         "scenario_I.toml", "robot.initial_joints_deg", "joint 4 outside"),
    Case("initial-joints-wrong-count",
         set_key(SCEN_I, "robot", "initial_joints_deg", "[0.0, 45.0, 0.0, 90.0, 0.0, 45.0]"),
         "scenario_I.toml", "robot.initial_joints_deg", "list of 7 numbers"),
    # URDF
    Case("urdf-limits-lower-gt-upper", urdf_joint3_limit("1.0", "-1.0"),
         "chaser7.urdf", "joint3", "lower must be < upper"),
    Case("urdf-missing", remove(URDF), "scenario_I.toml", "robot_urdf", "not found"),
    Case("urdf-not-xml", write(URDF, "this is not <xml at all\n"), "chaser7.urdf", None, "not valid XML"),
    Case("urdf-binary-garbage", write(URDF, b"\x00\xff\xfe garbage \x89PNG"), "chaser7.urdf", None, "XML"),
    Case("urdf-ee-frame-unknown", set_key(SCEN_I, "", "ee_frame", '"gripper_tip"'),
         "scenario_I.toml", "ee_frame", "gripper_tip"),
    # whole files
    Case("scenario-not-toml", write(SCEN_I, "name = scenario I\n[robot\n"), "scenario_I.toml", None, "TOML"),
    Case("scenario-binary-garbage", write(SCEN_I, b"\x89PNG\r\n\x1a\n\x00\xff\xfe"), "scenario_I.toml", None, "TOML"),
    Case("target-not-toml", write(TARGET_II, "mass_kg = = 3\n"), "scenario_II_target.toml", None, "TOML", SCEN_II),
    Case("target-missing", remove(TARGET_I), "scenario_I.toml", "target", "not found"),
    Case("scenario-missing", remove(SCEN_I), "scenario_I.toml", None, "not found"),
    # sanity limits (planner.config.limits): values that would cost hours or gigabytes before an answer
    Case("limit-stabilization-duration", set_key(SCEN_I, "phases", "stabilization_s", "1e9"),
         "scenario_I.toml", "phases.stabilization_s", "sanity limit"),
    Case("limit-via-points", set_key(SCEN_I, "approach", "via_points", "100000000"),
         "scenario_I.toml", "approach.via_points", "sanity limit"),
    Case("limit-cost-weight", set_key(SCEN_I, "costs", "min_distance", "1e12"),
         "scenario_I.toml", "costs.min_distance", "sanity limit"),
    Case("limit-tracking-step", set_key(SCEN_I, "tracking", "step_s", "1e-9"),
         "scenario_I.toml", "tracking.step_s", "sanity limit"),
    Case("limit-body-rate", set_key(SCEN_I, "target_state", "omega_body_deg_s", "[0.0, 0.0, 1e6]"),
         "scenario_I.toml", "target_state.omega_body_deg_s", "sanity limit"),
    Case("limit-box-size", set_key(TARGET_I, "shapes", "size_m", "[1e6, 1.0, 1.0]"),
         "scenario_I_target.toml", "shapes[0].size_m", "sanity limit"),
    Case("deeply-nested-array", append(SCEN_I, "deep = " + "[" * 5000 + "]" * 5000),
         "scenario_I.toml", None, "nested too deeply"),
    Case("huge-array", append(SCEN_I, "big = [" + ",".join(["0"] * 2_000_000) + "]"),
         "scenario_I.toml", None, "too large for a config"),
    Case("long-array-in-message",
         set_key(SCEN_I, "target_state", "attitude_wxyz", "[" + ",".join(["1"] * 100_000) + "]"),
         "scenario_I.toml", "target_state.attitude_wxyz", "[100000 items]"),
]
MAX_LINE_CHARS = 600  # an error quoting a huge value stays one readable line


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_config_gives_one_line_error(case: Case, tmp_path: Path) -> None:
    root = _copy_configs(tmp_path)
    case.mutation(root)
    result = _run(root / case.scenario)

    err = result.stderr
    assert "Traceback" not in err, err
    assert result.returncode == 1, (result.returncode, err)
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one stderr line, got {len(lines)}:\n{err}"
    line = lines[0]
    assert line.startswith("error: "), line
    assert len(line) <= MAX_LINE_CHARS, len(line)
    assert case.file in line, f"file {case.file!r} not named: {line}"
    if case.field is not None:
        # after the file name, as a whole dotted-path component: "phase" must not match "phases.x"
        rest = line.split(case.file, 1)[1]
        assert re.search(rf"(^|[\s.]){re.escape(case.field)}[:.\[]", rest), f"field {case.field!r} not named: {line}"
    assert case.problem.lower() in line.lower(), f"problem {case.problem!r} not in: {line}"
    assert "ok" not in result.stdout.splitlines(), result.stdout


@pytest.mark.parametrize("scenario", [SCEN_I, SCEN_II])
def test_bundled_scenarios_validate(scenario: str, tmp_path: Path) -> None:
    root = _copy_configs(tmp_path)
    result = _run(root / scenario)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert "37 body pairs; link7-handle may touch only at the grasp" in result.stdout
    assert result.stdout.splitlines()[-1] == "ok"
