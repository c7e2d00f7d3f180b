"""ATE equals evo's APE (translation part) for SE(3), Sim(3) and no alignment; SE(2) works."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from evo.core import metrics as evo_metrics
from evo.core import sync
from evo.core.trajectory import PoseTrajectory3D
from evo.tools import file_interface
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_rotation, rot2
from datasets.trajectory import Trajectory
from datasets.trajectory_io import read_tum, write_tum
from workbench.metrics.alignment import apply_alignment, estimate_alignment, lift_to_3d, umeyama
from workbench.metrics.ate import ate_report


def _trajectory(t: np.ndarray, rng: np.random.Generator, scale: float = 1.0) -> Trajectory:
    rotvecs = np.cumsum(rng.normal(0, 0.05, (len(t), 3)), axis=0)
    positions = scale * np.cumsum(rng.normal(0, 0.3, (len(t), 3)), axis=0)
    return Trajectory(
        t=t, positions=positions, rotations=quat_wxyz_from_rotation(Rotation.from_rotvec(rotvecs))
    )


def _distorted(
    truth: Trajectory, t: np.ndarray, rng: np.random.Generator, scale: float = 1.0
) -> Trajectory:
    """Truth resampled at ``t`` (nearest), moved by a random rigid transform, scaled, noisy."""
    nearest = np.clip(np.searchsorted(truth.t, t), 0, len(truth) - 1)
    rotation = Rotation.from_rotvec(rng.normal(0, 0.7, 3))
    positions = (
        scale * rotation.apply(truth.positions[nearest])
        + rng.normal(0, 5, 3)
        + rng.normal(0, 0.2, (len(t), 3))
    )
    rotations = quat_wxyz_from_rotation(
        rotation * Rotation.from_quat(truth.rotations[nearest][:, [1, 2, 3, 0]])
    )
    return Trajectory(t=t, positions=positions, rotations=rotations)


def _evo_rmse(
    reference: PoseTrajectory3D, estimate: PoseTrajectory3D, align: str, max_diff: float = 0.01
) -> float:
    reference, estimate = sync.associate_trajectories(reference, estimate, max_diff=max_diff)
    estimate = copy.deepcopy(estimate)
    if align in ("se3", "sim3"):
        estimate.align(reference, correct_scale=align == "sim3")
    metric = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    metric.process_data((reference, estimate))
    return metric.get_statistic(evo_metrics.StatisticsType.rmse)


PAIRS = {
    "same_stamps": (np.arange(0.0, 20.0, 0.1), np.arange(0.0, 20.0, 0.1)),
    "jittered": (
        np.arange(0.0, 20.0, 0.1),
        np.sort(np.arange(0.0, 20.0, 0.1) + np.random.default_rng(3).uniform(-0.015, 0.015, 200)),
    ),
    "different_rates": (np.arange(0.0, 20.0, 0.05), np.arange(0.004, 20.0, 0.3)),
    "partial_overlap": (np.arange(0.0, 20.0, 0.1), np.arange(8.0, 30.0, 0.1) + 0.006),
    "estimate_denser": (np.arange(0.0, 20.0, 0.2), np.arange(0.0, 20.0, 0.05) + 0.002),
}


@pytest.mark.parametrize("align", ["se3", "sim3", "none"])
@pytest.mark.parametrize("name", sorted(PAIRS))
def test_ate_report_equals_evo_on_tum_files(tmp_path: Path, name: str, align: str) -> None:
    rng = np.random.default_rng(11)
    t_ref, t_est = PAIRS[name]
    truth = _trajectory(t_ref, rng)
    estimate = _distorted(truth, t_est, rng, scale=1.3 if align == "sim3" else 1.0)
    ref_path, est_path = (
        write_tum(tmp_path / "ref.tum", truth),
        write_tum(tmp_path / "est.tum", estimate),
    )

    report = ate_report(read_tum(ref_path), read_tum(est_path), align=align)
    expected = _evo_rmse(
        file_interface.read_tum_trajectory_file(str(ref_path)),
        file_interface.read_tum_trajectory_file(str(est_path)),
        align,
    )
    assert report["rmse_m"] == pytest.approx(expected, rel=1e-6)
    assert report["pairs"] >= 1
    assert report["align"] == align


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    count=st.integers(3, 60),
    align=st.sampled_from(["se3", "sim3", "none"]),
    jitter=st.sampled_from([0.0, 0.004, 0.02]),
)
def test_ate_equals_evo_on_random_trajectories(
    seed: int, count: int, align: str, jitter: float
) -> None:
    rng = np.random.default_rng(seed)
    truth = _trajectory(np.arange(count) * 0.1, rng)
    t_est = np.sort(truth.t + rng.uniform(-jitter, jitter, count))
    estimate = _distorted(truth, t_est, rng, scale=float(rng.uniform(0.5, 2.0)))
    evo_ref = PoseTrajectory3D(truth.positions, truth.rotations, truth.t)
    evo_est = PoseTrajectory3D(estimate.positions, estimate.rotations, estimate.t)
    try:
        expected = _evo_rmse(evo_ref, evo_est, align)
    except Exception:  # evo found no pairs or a degenerate alignment: we must refuse too
        with pytest.raises(InputError):
            ate_report(truth, estimate, align=align)
        return
    assert ate_report(truth, estimate, align=align)["rmse_m"] == pytest.approx(
        expected, rel=1e-6, abs=1e-12
    )


def test_rigidly_moved_copy_has_zero_se3_error_and_known_raw_error() -> None:
    rng = np.random.default_rng(5)
    truth = _trajectory(np.arange(0.0, 10.0, 0.1), rng)
    rotation = Rotation.from_rotvec([0.4, -0.2, 1.1])
    translation = np.array([3.0, -4.0, 12.0])
    moved = Trajectory(
        truth.t,
        rotation.apply(truth.positions) + translation,
        quat_wxyz_from_rotation(rotation * Rotation.from_quat(truth.rotations[:, [1, 2, 3, 0]])),
    )
    report = ate_report(truth, moved, align="se3")
    assert report["rmse_m"] < 1e-9
    np.testing.assert_allclose(
        np.array(report["alignment"]["rotation"]), rotation.inv().as_matrix(), atol=1e-9
    )
    raw = ate_report(truth, moved, align="none")
    assert raw["rmse_m"] > 1.0
    assert raw["alignment"]["kind"] == "none"


def test_se2_alignment_recovers_a_planar_transform_and_keeps_planar_trajectories() -> None:
    rng = np.random.default_rng(8)
    t = np.arange(0.0, 10.0, 0.1)
    positions = np.cumsum(rng.normal(0, 0.3, (len(t), 2)), axis=0)
    headings = np.cumsum(rng.normal(0, 0.1, len(t)))
    truth = Trajectory(t, positions, headings)
    yaw, shift = 0.8, np.array([3.0, -2.0])
    estimate = Trajectory(t, positions @ rot2(yaw).T + shift, headings + yaw)
    alignment = estimate_alignment(truth, estimate, "se2")
    aligned = apply_alignment(estimate, alignment)
    assert aligned.dimension == 2
    np.testing.assert_allclose(aligned.positions, positions, atol=1e-9)
    np.testing.assert_allclose(np.cos(aligned.rotations - headings), 1.0, atol=1e-12)
    assert ate_report(truth, estimate, align="se2")["rmse_m"] < 1e-9


def test_se2_never_beats_se3_and_ignores_what_se3_would_mirror() -> None:
    rng = np.random.default_rng(9)
    t = np.arange(0.0, 10.0, 0.1)
    positions = np.cumsum(rng.normal(0, 0.3, (len(t), 2)), axis=0)
    truth = Trajectory(t, positions, np.zeros(len(t)))
    mirrored = Trajectory(t, positions * np.array([1.0, -1.0]), np.zeros(len(t)))
    se3 = ate_report(truth, mirrored, align="se3")["rmse_m"]
    se2 = ate_report(truth, mirrored, align="se2")["rmse_m"]
    # A 3-D rotation by pi about x un-mirrors the plane; a planar alignment cannot.
    assert se3 < 1e-9 < se2
    lifted = ate_report(lift_to_3d(truth), lift_to_3d(mirrored), align="se3")["rmse_m"]
    assert lifted == pytest.approx(se3, abs=1e-9)


def test_degenerate_and_unknown_alignments_are_input_errors() -> None:
    t = np.arange(5.0)
    static = Trajectory(t, np.zeros((5, 3)), np.tile([1.0, 0, 0, 0], (5, 1)))
    with pytest.raises(InputError, match="degenerate"):
        ate_report(static, static, align="se3")
    assert ate_report(static, static, align="se3", allow_degenerate=True)["rmse_m"] == 0.0
    with pytest.raises(InputError, match="unknown alignment"):
        ate_report(static, static, align="affine")


def test_umeyama_recovers_a_similarity() -> None:
    rng = np.random.default_rng(10)
    source = rng.normal(size=(30, 3))
    rotation = Rotation.from_rotvec([0.3, -1.0, 2.0]).as_matrix()
    target = 2.5 * source @ rotation.T + np.array([1.0, 2.0, 3.0])
    r, t, s = umeyama(source, target, with_scale=True)
    np.testing.assert_allclose(r, rotation, atol=1e-12)
    np.testing.assert_allclose(t, [1.0, 2.0, 3.0], atol=1e-12)
    assert s == pytest.approx(2.5, rel=1e-12)
