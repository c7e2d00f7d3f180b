"""RPE equals evo's RPE (frames and metres); the KITTI segment metric on known drifts."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from evo.core import metrics as evo_metrics
from evo.core import sync
from evo.tools import file_interface
from scipy.spatial.transform import Rotation

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_rotation
from datasets.trajectory import Trajectory
from datasets.trajectory_io import read_tum, write_tum
from workbench.metrics.rpe import kitti_segment_errors, pairs_by_distance, rpe_report


def _pair(
    rng: np.random.Generator, t_ref: np.ndarray, t_est: np.ndarray
) -> tuple[Trajectory, Trajectory]:
    rotvecs = np.cumsum(rng.normal(0, 0.05, (len(t_ref), 3)), axis=0)
    truth = Trajectory(
        t_ref,
        np.cumsum(rng.normal(0, 0.3, (len(t_ref), 3)), axis=0),
        quat_wxyz_from_rotation(Rotation.from_rotvec(rotvecs)),
    )
    nearest = np.clip(np.searchsorted(t_ref, t_est), 0, len(t_ref) - 1)
    noise = Rotation.from_rotvec(rng.normal(0, 0.02, (len(t_est), 3)))
    rotations = Rotation.from_quat(truth.rotations[nearest][:, [1, 2, 3, 0]]) * noise
    estimate = Trajectory(
        t_est,
        truth.positions[nearest] + rng.normal(0, 0.05, (len(t_est), 3)),
        quat_wxyz_from_rotation(rotations),
    )
    return truth, estimate


def _evo_rpe(
    ref_path: Path,
    est_path: Path,
    relation: evo_metrics.PoseRelation,
    delta: float,
    unit: evo_metrics.Unit,
    align: str,
) -> float:
    reference = file_interface.read_tum_trajectory_file(str(ref_path))
    estimate = file_interface.read_tum_trajectory_file(str(est_path))
    reference, estimate = sync.associate_trajectories(reference, estimate)
    estimate = copy.deepcopy(estimate)
    if align in ("se3", "sim3"):
        estimate.align(reference, correct_scale=align == "sim3")
    metric = evo_metrics.RPE(relation, delta, unit, all_pairs=False)
    metric.process_data((reference, estimate))
    return metric.get_statistic(evo_metrics.StatisticsType.rmse)


@pytest.mark.parametrize(
    ("delta", "unit", "align", "jitter"),
    [
        (1, "frames", "none", 0.0),
        (1, "frames", "se3", 0.006),
        (5, "frames", "sim3", 0.0),
        (2.0, "m", "none", 0.006),
        (3.0, "m", "sim3", 0.0),
    ],
)
def test_rpe_report_equals_evo(
    tmp_path: Path, delta: float, unit: str, align: str, jitter: float
) -> None:
    rng = np.random.default_rng(21)
    t_ref = np.arange(0.0, 20.0, 0.1)
    truth, estimate = _pair(rng, t_ref, np.sort(t_ref + rng.uniform(-jitter, jitter, len(t_ref))))
    ref_path, est_path = (
        write_tum(tmp_path / "ref.tum", truth),
        write_tum(tmp_path / "est.tum", estimate),
    )
    report = rpe_report(read_tum(ref_path), read_tum(est_path), delta=delta, unit=unit, align=align)
    evo_unit = evo_metrics.Unit.frames if unit == "frames" else evo_metrics.Unit.meters
    trans = _evo_rpe(
        ref_path, est_path, evo_metrics.PoseRelation.translation_part, delta, evo_unit, align
    )
    rot = _evo_rpe(
        ref_path, est_path, evo_metrics.PoseRelation.rotation_angle_deg, delta, evo_unit, align
    )
    assert report["trans_rmse_m"] == pytest.approx(trans, rel=1e-6)
    assert report["rot_rmse_deg"] == pytest.approx(rot, rel=1e-6)
    assert report["pairs"] > 3


def test_rpe_of_a_perfect_estimate_is_zero_and_bad_deltas_are_input_errors() -> None:
    rng = np.random.default_rng(22)
    truth, _ = _pair(rng, np.arange(0.0, 5.0, 0.1), np.arange(0.0, 5.0, 0.1))
    report = rpe_report(truth, truth, delta=1, unit="frames")
    assert report["trans_rmse_m"] < 1e-12 and report["rot_rmse_deg"] < 1e-6
    with pytest.raises(InputError, match="no pose pair"):
        rpe_report(truth, truth, delta=1000, unit="frames")
    with pytest.raises(InputError, match="integer"):
        rpe_report(truth, truth, delta=1.5, unit="frames")
    with pytest.raises(InputError, match="unknown RPE unit"):
        rpe_report(truth, truth, delta=1, unit="seconds")


def test_pairs_by_distance_restarts_the_count_at_every_pair() -> None:
    positions = np.column_stack([np.arange(11.0), np.zeros(11)])
    np.testing.assert_array_equal(pairs_by_distance(positions, 3.0), [[0, 3], [3, 6], [6, 9]])


def _straight_line(length_m: float, step_m: float) -> Trajectory:
    x = np.arange(0.0, length_m + step_m, step_m)
    return Trajectory(
        np.arange(len(x)) * 0.1,
        np.column_stack([x, np.zeros((len(x), 2))]),
        np.tile([1.0, 0, 0, 0], (len(x), 1)),
    )


def test_kitti_segments_of_a_scaled_path_give_the_scale_error_in_percent() -> None:
    truth = _straight_line(1000.0, 1.0)
    estimate = Trajectory(truth.t, 1.02 * truth.positions, truth.rotations)
    result = kitti_segment_errors(truth, estimate)
    # Segments end at the first frame beyond L, so each is L + 1 m long: 2% of (L+1) / L.
    expected = np.mean([2.0 * (length + 1.0) / length for length in range(100, 900, 100)])
    assert result["segments"] > 0
    assert result["rotation_deg_per_100m"] == pytest.approx(0.0, abs=1e-9)
    assert result["translation_percent"] == pytest.approx(expected, rel=0.02)


def test_kitti_segments_measure_heading_drift_per_100m() -> None:
    truth = _straight_line(900.0, 1.0)
    # Heading drifts 0.5 deg per 100 m of travel, positions exact.
    yaw = np.deg2rad(0.005) * truth.positions[:, 0]
    drifted = Trajectory(
        truth.t,
        truth.positions,
        quat_wxyz_from_rotation(Rotation.from_rotvec(np.outer(yaw, [0, 0, 1]))),
    )
    result = kitti_segment_errors(truth, drifted)
    assert result["rotation_deg_per_100m"] == pytest.approx(0.5, rel=0.02)


def test_kitti_segments_are_undefined_on_short_paths() -> None:
    truth = _straight_line(50.0, 1.0)
    assert kitti_segment_errors(truth, truth) == {
        "translation_percent": None,
        "rotation_deg_per_100m": None,
        "segments": 0,
    }


def _devkit_port(reference: Trajectory, estimate: Trajectory) -> tuple[float, float]:
    """A literal port of the KITTI devkit's calcSequenceErrors + averaging (acos angle)."""
    gt, result = reference.homogeneous(), estimate.homogeneous()
    dist = [0.0]
    for i in range(1, len(gt)):
        dist.append(dist[-1] + float(np.linalg.norm(gt[i, :3, 3] - gt[i - 1, :3, 3])))
    t_errs, r_errs = [], []
    for first in range(0, len(gt), 10):
        for length in (100, 200, 300, 400, 500, 600, 700, 800):
            last = next((i for i in range(first, len(dist)) if dist[i] > dist[first] + length), -1)
            if last == -1:
                continue
            delta_gt = np.linalg.inv(gt[first]) @ gt[last]
            delta_result = np.linalg.inv(result[first]) @ result[last]
            error = np.linalg.inv(delta_result) @ delta_gt
            r_errs.append(
                np.arccos(max(min(0.5 * (np.trace(error[:3, :3]) - 1.0), 1.0), -1.0)) / length
            )
            t_errs.append(np.linalg.norm(error[:3, 3]) / length)
    return 100.0 * float(np.mean(t_errs)), 100.0 * float(np.rad2deg(np.mean(r_errs)))


def test_kitti_segments_equal_a_literal_devkit_port() -> None:
    rng = np.random.default_rng(23)
    count = 600
    steps = np.column_stack([np.full(count, 1.0), rng.normal(0, 0.2, (count, 2))])
    truth = Trajectory(
        np.arange(count) * 0.1,
        np.cumsum(steps, axis=0),
        quat_wxyz_from_rotation(
            Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.01, (count, 3)), axis=0))
        ),
    )
    drift = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.002, (count, 3)), axis=0))
    estimate = Trajectory(
        truth.t,
        truth.positions + np.cumsum(rng.normal(0, 0.05, (count, 3)), axis=0),
        quat_wxyz_from_rotation(Rotation.from_quat(truth.rotations[:, [1, 2, 3, 0]]) * drift),
    )
    result = kitti_segment_errors(truth, estimate)
    translation, rotation = _devkit_port(truth, estimate)
    assert result["segments"] > 100
    assert result["translation_percent"] == pytest.approx(translation, rel=1e-9)
    assert result["rotation_deg_per_100m"] == pytest.approx(rotation, rel=1e-6)
