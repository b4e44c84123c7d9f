"""Each kind of config or state failure raises its own exception class, carrying the file, field and value."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.errors import (
    ConfigError,
    ConfigFileError,
    FieldTypeError,
    FieldValueError,
    MissingFieldError,
    NonUnitQuaternionError,
    RobotModelError,
    SanityLimitError,
    StateFieldError,
    TargetStateError,
    UnknownFieldError,
)
from planner.model.target_state import TargetState
from tests.planner.config.test_config_errors import (
    SCEN_I,
    TARGET_I,
    URDF,
    Mutation,
    _copy_configs,
    append,
    remove,
    set_key,
    write,
)

CASES = [
    ("missing-file", remove(SCEN_I), ConfigFileError, "", None),
    ("not-toml", write(SCEN_I, "name = scenario I\n[robot\n"), ConfigFileError, "", None),
    ("unknown-field", append(SCEN_I, "\n[extra]\nx = 1\n"), UnknownFieldError, "extra", None),
    ("wrong-type", set_key(SCEN_I, "phases", "approach_s", '"ten"'), FieldTypeError, "phases.approach_s", "ten"),
    ("bad-value", set_key(SCEN_I, "phases", "approach_s", "-1.0"), FieldValueError, "phases.approach_s", -1.0),
    ("sanity-limit", set_key(SCEN_I, "phases", "stabilization_s", "1e9"), SanityLimitError,
     "phases.stabilization_s", 1e9),
    ("target-bad-mass", set_key(TARGET_I, "", "mass_kg", "-3.0"), FieldValueError, "mass_kg", -3.0),
    ("urdf-not-xml", write(URDF, "<robot"), ConfigFileError, "", None),
    ("ee-frame", set_key(SCEN_I, "", "ee_frame", '"gripper_tip"'), FieldValueError, "ee_frame", "gripper_tip"),
]


@pytest.mark.parametrize(("mutation", "kind", "field", "value"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_each_config_failure_has_its_class(mutation: Mutation, kind: type[ConfigError], field: str, value: object,
                                           tmp_path: Path) -> None:
    root = _copy_configs(tmp_path)
    mutation(root)
    with pytest.raises(kind) as info:
        load_scenario(root / SCEN_I)
    assert isinstance(info.value, ConfigError)
    assert info.value.field == field
    assert str(info.value).startswith(info.value.source)
    if value is not None:
        assert info.value.value == value


def test_a_missing_field_names_it(tmp_path: Path) -> None:
    root = _copy_configs(tmp_path)
    path = root / SCEN_I
    path.write_text(path.read_text().replace("max_start_delay_s", "# max_start_delay_s", 1))
    with pytest.raises(MissingFieldError) as info:
        load_scenario(path)
    assert info.value.field == "phases.max_start_delay_s"
    assert str(info.value).endswith("phases.max_start_delay_s: missing required field")


def test_a_robot_that_is_not_a_chain_is_a_robot_model_error(tmp_path: Path) -> None:
    from planner.model.urdf import load_robot

    root = _copy_configs(tmp_path)
    with pytest.raises(RobotModelError) as info:
        load_robot(root / URDF, ee_frame="no_such_frame")
    assert info.value.field == "ee_frame"


def test_state_errors_carry_the_field_and_value() -> None:
    with pytest.raises(NonUnitQuaternionError) as info:
        TargetState(np.array([2.0, 0.0, 0.0, 0.0]), np.zeros(3))
    assert info.value.field == "attitude_wxyz"
    assert info.value.norm == 2.0
    assert str(info.value).startswith("attitude_wxyz: must be a unit quaternion")
    with pytest.raises(StateFieldError) as info:
        TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, np.nan, 0.0]))
    assert isinstance(info.value, TargetStateError)
    assert info.value.field == "omega_body_rad_s"
