"""Aghili filter: boundary conversion, O(n) propagation, bad input, NEES consistency, adaptive R."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.measurements import ImuSample, LandmarkScan
from datasets.simulation.scenarios import load_scenario
from filters.aghili import quaternion_jpl as quat
from filters.aghili.filter import AghiliConfig, AghiliFilter
from workbench.metrics.consistency import averaged_nees, nees, pose_errors
from workbench.sweep.backends import LocalBackend


def rover(seed: int, **options: str):
    return load_scenario("aghili-rover", seed, {"duration_s": "10", **options})


def run(sequence, **config) -> tuple[AghiliFilter, object]:
    f = AghiliFilter(AghiliConfig(**config), sequence)
    for measurement in sequence.measurements():
        f.process(measurement)
    return f, f.estimate()


def test_pose_covariance_boundary_matches_monte_carlo_of_internal_errors() -> None:
    """Sample internal errors [dq_v, dr_world] from P, form interface errors the way the
    metrics do (Log(R_est^T R_true), R_est^T (p_true - p_est)), compare covariances."""
    f = AghiliFilter(AghiliConfig(), rover(0))
    rng = np.random.default_rng(0)
    f.q = quat.from_interface_wxyz(np.array([0.9, 0.1, -0.3, 0.2]))
    L = rng.normal(size=(6, 6)) * 1e-3
    f.P[:6, :6] = L @ L.T
    exported = f.interface_pose_covariance()
    samples = rng.multivariate_normal(np.zeros(6), f.P[:6, :6], size=20000)
    from datasets.rotations import so3_log

    A = quat.rotation_matrix(f.q)
    errors = []
    for dx in samples:
        true_A = quat.rotation_matrix(quat.apply_error(dx[:3], f.q))
        errors.append(np.r_[so3_log(A.T @ true_A), A.T @ dx[3:6]])
    np.testing.assert_allclose(
        np.cov(np.array(errors).T), exported, atol=0.05 * np.abs(exported).max()
    )


def test_bias_sign_and_initial_covariances_at_the_interface() -> None:
    f = AghiliFilter(AghiliConfig(), rover(0))
    assert np.all(np.diag(f.P)[6:15] > 0)  # velocity and biases: nonzero initial covariance
    f.b_g = np.array([1e-3, 0.0, 0.0])
    f._record()
    estimate = f.estimate()
    np.testing.assert_allclose(estimate.causal.block("gyro_bias").values[-1], [-1e-3, 0.0, 0.0])


def test_propagation_leaves_the_landmark_block_untouched() -> None:
    f, _ = run(rover(0, duration_s="3"))
    assert len(f.landmark_ids) > 0
    before = f.P[15:, 15:].copy()
    f.process(ImuSample(f.t + 0.05, np.array([0.01, 0.0, 0.02]), np.array([0.0, 0.0, 9.81])))
    np.testing.assert_array_equal(f.P[15:, 15:], before)


def test_bad_input_is_an_error_and_the_state_stays_finite() -> None:
    f, _ = run(rover(0, duration_s="2"))
    t = f.t
    with pytest.raises(InputError, match="non-finite"):
        f.process(ImuSample(t + 0.05, np.array([np.nan, 0.0, 0.0]), np.array([0.0, 0.0, 9.81])))
    with pytest.raises(InputError, match="backwards"):
        f.process(ImuSample(t - 1.0, np.zeros(3), np.array([0.0, 0.0, 9.81])))
    f.process(
        LandmarkScan(t + 0.01, np.zeros((0, 3)), np.zeros((0, 3, 3)), ids=np.zeros(0, dtype=int))
    )
    f.process(ImuSample(t + 0.05, np.zeros(3), np.array([0.0, 0.0, 9.81])))
    assert f.counts["empty_scans"] == 1
    assert np.all(np.isfinite(f.P)) and np.all(np.isfinite(f.q)) and np.all(np.isfinite(f.r))
    assert any("empty landmark scans" in note for note in f.estimate().notes)


def test_first_observation_anchors_say_nees_is_not_comparable() -> None:
    _, estimate = run(rover(0, duration_s="3"), anchor_source="first-observation")
    assert any("not comparable" in note for note in estimate.notes)


def _low_noise_pose_nees(seed: int) -> np.ndarray:
    """Per-step pose NEES (6 dof) of one run of the test below, in a worker process."""
    sequence = load_scenario("aghili-rover", seed, {"duration_s": "30", "noise_scale": "0.1"})
    _, estimate = run(sequence, anchors=3)
    pose, truth = estimate.causal.pose, sequence.ground_truth.pose
    index = np.clip(np.searchsorted(truth.t, pose.t), 0, len(truth.t) - 1)
    assert np.allclose(truth.t[index], pose.t)
    return nees(pose_errors(pose, truth.select(index)), pose.covariances)


@pytest.mark.study
def test_averaged_pose_nees_is_inside_the_95_percent_bounds() -> None:
    """20 seeds x 30 s, low noise, 3 anchors: averaged pose NEES (6 dof) inside the two-sided
    95% bounds for >= 80% of the steps (catches a wrong Q or transition matrix)."""
    backend = LocalBackend(2)  # 20 independent runs on the sweep's workers (2 cores)
    try:
        futures = [backend.submit(_low_noise_pose_nees, seed) for seed in range(20)]
        runs = [future.result() for future in futures]
    finally:
        backend.close()
    steps = min(len(r) for r in runs)
    result = averaged_nees(np.array([r[:steps] for r in runs]), dof=6)
    assert result.inside_fraction >= 0.8, result.inside_fraction


@pytest.mark.parametrize(
    "seed", [1, *(pytest.param(seed, marks=pytest.mark.study) for seed in (2, 3, 4, 5))]
)
def test_adaptive_r_converges_from_a_tenfold_wrong_guess(seed: int) -> None:
    """True sigma 0.2 m; initial R 10x too large (variance). Adapted R within 25% of truth;
    ATE within 10% of the filter given the true R. The first five seeds, not chosen ones:
    ``benchmarks/bench_aghili_adaptive_r.py`` measured seeds 1-10, 9 of 10 within 10%
    (seed 9: +19%, from the warm-up before the window holds 30 residuals). The paper's
    prior-residual form fails all ten (x3.5 to x496)."""
    options = {"duration_s": "60", "landmark_sigma_min_m": "0.2", "landmark_sigma_max_m": "0.2"}
    sequence = load_scenario("aghili-rover", seed, options)
    truth = sequence.ground_truth.pose

    def position_rmse(estimate) -> float:
        pose = estimate.causal.pose
        index = np.clip(np.searchsorted(truth.t, pose.t), 0, len(truth.t) - 1)
        return float(
            np.sqrt(np.mean(np.sum((pose.positions - truth.positions[index]) ** 2, axis=1)))
        )

    adaptive, adaptive_estimate = run(
        sequence, landmark_measurement_sigma_m=0.2 * np.sqrt(10.0), adaptive_noise=True
    )
    _, reference_estimate = run(sequence, landmark_measurement_sigma_m=0.2, adaptive_noise=False)
    variances = np.diag(adaptive.noise_window.estimate())
    np.testing.assert_allclose(variances, 0.04, rtol=0.25)
    assert position_rmse(adaptive_estimate) <= 1.1 * position_rmse(reference_estimate)
