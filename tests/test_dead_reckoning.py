"""Dead reckoning: exact on noise-free data, consistent covariance on noisy data."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from filters.dead_reckoning import DeadReckoning, pose2_inverse_adjoint
from workbench.metrics.consistency import averaged_nees
from workbench.metrics.state_errors import nees_series
from workbench.registry import load_dataset
from workbench.runner import resolve_config, run_estimator


def run(dataset: str, seed: int, options: dict[str, str]):
    sequence = load_dataset(dataset, seed, options)
    return sequence, run_estimator(DeadReckoning, resolve_config(DeadReckoning), sequence)


@pytest.mark.parametrize("dataset", ["sim:aghili-rover", "sim:circle"])
def test_noise_free_imu_integration_follows_truth(dataset):
    sequence, estimate = run(dataset, 1, {"duration_s": "20", "noise_scale": "0"})
    truth = sequence.ground_truth.pose
    index = np.searchsorted(truth.t, estimate.causal.pose.t)
    assert np.allclose(truth.t[index], estimate.causal.pose.t)
    position_error = np.linalg.norm(truth.positions[index] - estimate.causal.pose.positions, axis=1)
    assert position_error.max() < 0.02  # 20 s of 20-100 Hz integration, no noise


def test_pose2_inverse_adjoint_matches_gtsam():
    rng = np.random.default_rng(0)
    for increment in rng.normal(size=(5, 3)):
        assert np.allclose(
            pose2_inverse_adjoint(increment), gtsam.Pose2(*increment).inverse().AdjointMap()
        )


def test_imu_covariance_is_consistent_over_monte_carlo_runs():
    runs: dict[str, list[np.ndarray]] = {}
    for seed in range(20):
        sequence, estimate = run("sim:aghili-rover", seed, {"duration_s": "10"})
        for name, series in nees_series(estimate.causal, sequence.ground_truth).items():
            runs.setdefault(name, []).append(series.nees)
    for name, dof in (("pose", 6), ("position", 3), ("velocity", 3)):
        result = averaged_nees(np.array(runs[name]), dof)
        assert result.inside_fraction >= 0.8, (
            name,
            result.inside_fraction,
            float(result.mean.mean()),
        )


def test_gyro_only_planar_dead_reckoning_runs():
    sequence, estimate = run("sim:guerreiro-loop", 1, {"duration_s": "20"})
    pose = estimate.causal.pose
    assert pose.dimension == 2 and len(pose) > 100
    assert np.all(np.isfinite(pose.covariances))
    assert np.all(np.linalg.eigvalsh(pose.covariances[-1]) > 0)
