"""Runner: sensor compatibility checks and config resolution."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.measurements import Sensor
from datasets.sequence import Sequence
from filters.dead_reckoning import DeadReckoning
from workbench.runner import check_compatible, resolve_config


def sequence_with(sensors, dimension=3):
    return Sequence(
        name="fake", dimension=dimension, sensors=frozenset(sensors), stream=lambda: iter(())
    )


def test_missing_sensor_is_named():
    with pytest.raises(
        InputError,
        match="needs sensor\\(s\\) imu \\| odometry \\| gyro, which dataset 'fake' does not provide \\(it provides: landmarks\\)",
    ):
        check_compatible("dead-reckoning", DeadReckoning, sequence_with({Sensor.LANDMARKS}))


def test_any_alternative_suffices():
    check_compatible(
        "dead-reckoning",
        DeadReckoning,
        sequence_with({Sensor.ODOMETRY, Sensor.LANDMARKS}, dimension=2),
    )


def test_config_file_then_set_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("max_gap_s: 2.5\ngyro_velocity_sigma_m_s2: 0.3\n")
    config = resolve_config(DeadReckoning, path, {"max_gap_s": "4"})
    assert config.max_gap_s == 4.0 and np.isclose(config.velocity_walk_m_s_sqrt_s, 0.3)


def test_bad_config_value_names_key(tmp_path):
    with pytest.raises(InputError, match="max_gap_s"):
        resolve_config(DeadReckoning, None, {"max_gap_s": "-1"})


def test_an_estimator_never_sees_the_ground_truth() -> None:
    """The runner builds every estimator on a view of the sequence without its truth."""
    from workbench.registry import load_dataset
    from workbench.runner import run_estimator

    seen = []

    class Spy(DeadReckoning):
        def __init__(self, config, sequence) -> None:
            seen.append(sequence.ground_truth)
            super().__init__(config, sequence)

    sequence = load_dataset("sim:circle", 0, {"duration_s": "1"})
    assert sequence.ground_truth is not None
    run_estimator(Spy, resolve_config(DeadReckoning), sequence)
    assert seen == [None]
