"""Stamp pairing reproduces evo's, and truth lookup interpolates as documented."""

from __future__ import annotations

import numpy as np
import pytest
from evo.core import sync
from evo.core.trajectory import PoseTrajectory3D
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_rotation, rotation_from_quat_wxyz
from datasets.trajectory import Trajectory
from workbench.metrics.timestamps import associate, matching_time_indices, trajectory_at, vectors_at


def _trajectory(t: np.ndarray, rng: np.random.Generator) -> Trajectory:
    rotations = quat_wxyz_from_rotation(
        Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.1, (len(t), 3)), axis=0))
    )
    return Trajectory(
        t=t, positions=np.cumsum(rng.normal(0, 1, (len(t), 3)), axis=0), rotations=rotations
    )


def _evo(trajectory: Trajectory) -> PoseTrajectory3D:
    return PoseTrajectory3D(
        trajectory.positions.copy(), trajectory.rotations.copy(), trajectory.t.copy()
    )


stamps = st.lists(st.floats(0.0, 2.0, allow_nan=False), min_size=1, max_size=40)


@settings(max_examples=150, deadline=None)
@given(stamps, stamps, st.sampled_from([0.0, 0.005, 0.01, 0.05]), st.booleans())
def test_matching_equals_evo(
    first: list[float], second: list[float], max_diff: float, sort_second: bool
) -> None:
    stamps_1 = np.round(np.array(first), 2)  # rounding creates exact ties and duplicates
    stamps_2 = np.round(np.array(second), 3)
    if sort_second:
        stamps_2 = np.sort(stamps_2)
    ours = matching_time_indices(stamps_1, stamps_2, max_diff)
    theirs = sync.matching_time_indices(stamps_1, stamps_2.copy(), max_diff)
    assert ours[0].tolist() == list(theirs[0])
    assert ours[1].tolist() == list(theirs[1])


@pytest.mark.parametrize(
    "case",
    ["identical", "jittered", "different_rates", "partial_overlap", "estimate_longer"],
)
def test_associate_equals_evo(case: str) -> None:
    rng = np.random.default_rng(7)
    t_ref = np.arange(0.0, 10.0, 0.1)
    t_est = {
        "identical": t_ref.copy(),
        "jittered": t_ref + rng.uniform(-0.012, 0.012, len(t_ref)),
        "different_rates": np.arange(0.003, 10.0, 0.25),
        "partial_overlap": np.arange(5.0, 15.0, 0.1) + 0.004,
        "estimate_longer": np.arange(0.0, 10.0, 0.02) + 0.001,
    }[case]
    t_est = np.sort(t_est)
    reference, estimate = _trajectory(t_ref, rng), _trajectory(t_est, rng)
    ref_indices, est_indices = associate(reference, estimate)
    evo_ref, evo_est = sync.associate_trajectories(_evo(reference), _evo(estimate))
    np.testing.assert_array_equal(reference.t[ref_indices], evo_ref.timestamps)
    np.testing.assert_array_equal(estimate.t[est_indices], evo_est.timestamps)
    np.testing.assert_array_equal(reference.positions[ref_indices], evo_ref.positions_xyz)
    assert len(ref_indices) > 0


def test_no_overlap_is_an_input_error() -> None:
    rng = np.random.default_rng(0)
    reference = _trajectory(np.arange(0.0, 1.0, 0.1), rng)
    estimate = _trajectory(np.arange(5.0, 6.0, 0.1), rng)
    with pytest.raises(InputError, match=r"no matching timestamps .* within 0.01 s"):
        associate(reference, estimate)


def test_exact_stamps_are_returned_unchanged() -> None:
    rng = np.random.default_rng(1)
    truth = _trajectory(np.arange(0.0, 2.0, 0.1), rng)
    query = truth.t[[0, 3, 19]] + np.array([0.0, 5e-7, -5e-7])
    found, valid = trajectory_at(truth, query)
    assert valid.all()
    np.testing.assert_array_equal(found.positions, truth.positions[[0, 3, 19]])
    np.testing.assert_array_equal(found.rotations, truth.rotations[[0, 3, 19]])


def test_interpolation_matches_scipy_slerp_and_linear() -> None:
    rng = np.random.default_rng(2)
    truth = _trajectory(np.arange(0.0, 2.0, 0.1), rng)
    query = np.array([-0.05, 0.05, 0.37, 1.234, 1.9, 1.95])
    found, valid = trajectory_at(truth, query)
    np.testing.assert_array_equal(valid, [False, True, True, True, True, False])
    expected = Slerp(truth.t, rotation_from_quat_wxyz(truth.rotations))(query[valid])
    angle = (expected.inv() * rotation_from_quat_wxyz(found.rotations)).magnitude()
    assert np.max(angle) < 1e-9
    for axis in range(3):
        np.testing.assert_allclose(
            found.positions[:, axis], np.interp(query[valid], truth.t, truth.positions[:, axis])
        )


def test_planar_headings_interpolate_along_the_short_arc() -> None:
    truth = Trajectory(
        t=np.array([0.0, 1.0]), positions=np.zeros((2, 2)), rotations=np.array([3.0, -3.0])
    )
    found, valid = trajectory_at(truth, np.array([0.5]))
    assert valid.all()
    # From 3.0 to -3.0 rad the short way crosses pi (0.283 rad of travel), not zero.
    assert abs(abs(found.rotations[0]) - np.pi) < 1e-9


def test_vectors_at_interpolates_linearly() -> None:
    values, valid = vectors_at(
        np.array([0.0, 1.0, 3.0]), np.array([[0.0], [2.0], [6.0]]), np.array([0.5, 2.0, 4.0])
    )
    np.testing.assert_array_equal(valid, [True, True, False])
    np.testing.assert_allclose(values[:, 0], [1.0, 4.0])
