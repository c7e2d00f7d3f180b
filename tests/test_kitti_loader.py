"""``kitti-imu-gps``: the gtsam wheel's KITTI IMU/GPS files as a sequence with held-out fixes."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.kitti_imu_gps import GPS_FILE, IMU_FILE, METADATA_FILE
from datasets.measurements import GpsFix, ImuSample, Sensor
from datasets.simulation.imu import gtsam_data_folder
from workbench.registry import load_dataset


def _fixes(sequence):
    return [m for m in sequence.measurements() if isinstance(m, GpsFix)]


def test_kitti_sequence_holds_out_the_requested_fraction_and_keeps_it_out_of_the_stream():
    sequence = load_dataset("kitti-imu-gps", 1, {"holdout_fraction": "0.3"})
    assert sequence.dimension == 3 and sequence.sensors == frozenset({Sensor.IMU, Sensor.GPS})
    used = _fixes(sequence)
    held_t, held_positions = sequence.ground_truth.held_out_positions
    total = len(used) + len(held_t)
    assert total == 469  # fixes from #1 (after the IMU gap) to the end
    assert abs(len(held_t) - 0.3 * (total - 2)) <= 1
    used_t = np.array([fix.t for fix in used])
    assert not np.intersect1d(used_t, held_t).size
    assert held_positions.shape == (len(held_t), 3)
    # The start (fix #1) and the next fix define the initial state and are never held out.
    assert used_t[0] == sequence.initial_state.t and used[0].t < held_t.min()
    assert np.allclose(used[0].position, sequence.initial_state.position)
    # The metadata file's densities are the noise spec, gtsam's example gravity the sequence's.
    assert sequence.noise.gyro_noise_density == pytest.approx(0.000175)
    assert sequence.noise.accel_bias_walk == pytest.approx(0.000167)
    assert sequence.gravity_m_s2 == 9.8


def test_kitti_stream_is_time_ordered_starts_after_the_imu_gap_and_depends_on_the_seed():
    sequence = load_dataset("kitti-imu-gps", 1, {"duration_s": "30"})
    items = list(sequence.measurements())
    times = np.array([m.t for m in items])
    assert np.all(np.diff(times) >= 0)
    imu_t = np.array([m.t for m in items if isinstance(m, ImuSample)])
    assert imu_t[0] <= sequence.initial_state.t and np.max(np.diff(imu_t)) < 0.05
    other = load_dataset("kitti-imu-gps", 2, {"duration_s": "30"})
    again = load_dataset("kitti-imu-gps", 1, {"duration_s": "30"})
    assert np.array_equal(
        again.ground_truth.held_out_positions[0], sequence.ground_truth.held_out_positions[0]
    )
    assert not np.array_equal(
        other.ground_truth.held_out_positions[0], sequence.ground_truth.held_out_positions[0]
    )


def test_malformed_kitti_files_are_input_errors_naming_file_and_line(tmp_path):
    source = gtsam_data_folder()
    for name in (IMU_FILE, GPS_FILE, METADATA_FILE):
        shutil.copy(source / name, tmp_path / name)
    lines = (tmp_path / IMU_FILE).read_text().splitlines()
    lines[5] = lines[5].replace(" ", " x", 1)
    (tmp_path / IMU_FILE).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=rf"{IMU_FILE}:6: a value is not a number"):
        load_dataset("kitti-imu-gps", 0, {"folder": str(tmp_path)})
    with pytest.raises(InputError, match="holdout_fraction"):
        load_dataset("kitti-imu-gps", 0, {"holdout_fraction": "1.5"})


@pytest.mark.study
def test_isam2_on_kitti_beats_dead_reckoning_on_held_out_fixes():
    from filters.dead_reckoning import DeadReckoning
    from smoothers.modes import SmootherIsam2

    sequence = load_dataset("kitti-imu-gps", 1, {"duration_s": "40", "holdout_fraction": "0.3"})
    held_t, held_positions = sequence.ground_truth.held_out_positions

    def holdout_rmse(trajectory) -> float:
        estimated = np.column_stack(
            [np.interp(held_t, trajectory.t, trajectory.positions[:, i]) for i in range(3)]
        )
        return float(np.sqrt(np.mean(np.sum((estimated - held_positions) ** 2, axis=1))))

    smoother = SmootherIsam2(
        SmootherIsam2.Config(keyframe_imu_stride=10, causal_covariances=False), sequence
    )
    reckoning = DeadReckoning(DeadReckoning.Config(), sequence)
    for measurement in sequence.measurements():
        smoother.process(measurement)
        reckoning.process(measurement)
    smoothed = holdout_rmse(smoother.estimate().smoothed.pose)
    dead = holdout_rmse(reckoning.estimate().causal.pose)
    assert smoothed < 1.5 and smoothed < dead / 5
