"""A scenario variant (``extends``) is its base with only the fields it gives replaced, and a table knows both."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from lut.table.model_identity import table_hash
from planner.config.scenario import load_scenario
from planner.config.variant import TEXT_SEPARATOR, identity_name
from planner.errors import ConfigError, UnknownFieldError

ROOT = Path(__file__).resolve().parents[3]
SCENARIOS = ROOT / "configs" / "scenarios"
VARIANTS = {"scenario_I_energy": ("scenario_I", {"approach_energy": 1.0}),
            "scenario_I_safety": ("scenario_I", {"manipulability": 1.0, "min_distance": 1.0}),
            "scenario_II_energy": ("scenario_II", {"approach_energy": 1.0}),
            "scenario_II_safety": ("scenario_II", {"manipulability": 1.0, "min_distance": 1.0})}


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_a_bundled_variant_is_its_base_but_for_the_name_and_the_costs(variant):
    base_name, weights = VARIANTS[variant]
    v, base = load_scenario(SCENARIOS / f"{variant}.toml"), load_scenario(SCENARIOS / f"{base_name}.toml")
    assert v.name == variant
    # every weight the variant does not give is the base's (the [costs] table is merged key by key)
    assert v.costs == dataclasses.replace(base.costs, **weights)
    for field in dataclasses.fields(base):
        if field.name in ("source", "text", "name", "costs", "robot", "target", "base_source"):
            continue
        mine, theirs = getattr(v, field.name), getattr(base, field.name)
        if dataclasses.is_dataclass(mine):
            mine, theirs = dataclasses.asdict(mine), dataclasses.asdict(theirs)
        np.testing.assert_equal(mine, theirs, err_msg=field.name)
    assert v.robot.urdf_path == base.robot.urdf_path and v.target.source == base.target.source
    assert v.text.startswith(base.text) and table_hash(v) != table_hash(base)
    assert v.base_source == str(SCENARIOS / f"{base_name}.toml") and base.base_source is None


def _copy_pair(tmp_path: Path, variant_text: str) -> Path:
    """scenario_I.toml and its robot/target folders copied under ``tmp_path``, and a variant next to it."""
    for folder in ("scenarios", "robots", "targets"):
        shutil.copytree(ROOT / "configs" / folder, tmp_path / folder)
    path = tmp_path / "scenarios" / "variant.toml"
    path.write_text(variant_text)
    return path


@pytest.mark.parametrize("base_name", ["scenario_I", "scenario_II"])
def test_the_wide_variant_is_its_base_but_for_the_name_and_a_base_offset_box_of_2_m(base_name):
    v = load_scenario(SCENARIOS / f"{base_name}_wide.toml")
    base = load_scenario(SCENARIOS / f"{base_name}.toml")
    assert v.name == f"{base_name}_wide" and base.base_offset_bounds_m == ((-1.0, 1.0), (-1.0, 1.0))
    assert v.base_offset_bounds_m == ((-2.0, 2.0), (-2.0, 2.0))
    # the [robot] table is merged key by key: the start configuration and the guess stay the base's
    np.testing.assert_equal(v.base_offset_guess_m, base.base_offset_guess_m)
    np.testing.assert_equal(v.q_initial, base.q_initial)
    assert v.limits == base.limits and v.phases == base.phases and v.costs == base.costs
    assert table_hash(v) != table_hash(base)


def test_a_change_of_the_base_makes_the_variants_tables_stale(tmp_path):
    path = _copy_pair(tmp_path, 'extends = "scenario_I.toml"\nname = "v"\n[costs]\napproach_energy = 2.0\n')
    before = table_hash(load_scenario(path))
    base = tmp_path / "scenarios" / "scenario_I.toml"
    base.write_text(base.read_text().replace("collision_margin_m = 0.02", "collision_margin_m = 0.03"))
    changed = load_scenario(path)
    assert changed.limits.collision_margin_m == pytest.approx(0.03)  # the base's value, inherited
    assert table_hash(changed) != before


@pytest.mark.parametrize("extends, words", [
    ('"missing.toml"', ("extends", "file not found")),
    ('"../scenarios/scenario_I.toml"', ("extends", "same folder")),
    ('"variant.toml"', ("extends", "cannot extend itself")),
    ('"chained.toml"', ("extends", "one level only")),
    ("3", ("extends", "same folder")),
])
def test_a_variant_naming_no_usable_base_is_refused_in_one_line(tmp_path, extends, words):
    path = _copy_pair(tmp_path, f'extends = {extends}\nname = "v"\n')
    (path.parent / "chained.toml").write_text('extends = "scenario_I.toml"\nname = "c"\n')
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message and all(w in message for w in words), message


def test_a_variants_unknown_field_is_refused_like_the_bases(tmp_path):
    path = _copy_pair(tmp_path, 'extends = "scenario_I.toml"\nname = "v"\n[costs]\napproach_energie = 1.0\n')
    with pytest.raises(UnknownFieldError, match="costs.approach_energie"):
        load_scenario(path)


def test_a_plan_is_never_written_over_the_base_of_its_variant(tmp_path):
    from tests.support.cli import assert_one_line_error, lutgen_in_process

    path = _copy_pair(tmp_path, 'extends = "scenario_I.toml"\nname = "v"\n')
    base = tmp_path / "scenarios" / "scenario_I.toml"
    before = base.read_bytes()
    assert_one_line_error(lutgen_in_process("plan", path, "--out", base), "--out")
    assert base.read_bytes() == before


@pytest.mark.parametrize("name", ["scenario_I", "scenario_II", *VARIANTS])
def test_the_identity_text_names_its_scenario(name):
    """A table stores the identity text; a variant's is its base's text then its own (two TOML documents, both with
    a [costs] table): its name is the variant's."""
    assert identity_name(load_scenario(SCENARIOS / f"{name}.toml").text) == name


def test_a_variant_without_a_name_of_its_own_is_named_by_its_base(tmp_path):
    shutil.copy(SCENARIOS / "scenario_II.toml", tmp_path / "base.toml")
    (tmp_path / "variant.toml").write_text('extends = "base.toml"\n[costs]\napproach_energy = 1.0\n', encoding="utf-8")
    text = (tmp_path / "base.toml").read_text(encoding="utf-8") + TEXT_SEPARATOR.format(name="variant.toml") + \
        (tmp_path / "variant.toml").read_text(encoding="utf-8")
    assert identity_name(text) == "scenario_II"
    with pytest.raises(ConfigError):
        identity_name("[costs]\napproach_energy = 1.0\n")
