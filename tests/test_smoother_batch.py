"""Batch smoother: consistency over Monte Carlo seeds, and its initialisation."""

from __future__ import annotations

import numpy as np
import pytest

from smoothers.modes import SmootherBatch
from workbench.metrics.consistency import averaged_nees, nees
from workbench.metrics.state_errors import pose_error_series
from workbench.registry import load_dataset


def _run(estimator_class, config, sequence):
    estimator = estimator_class(config, sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()


@pytest.mark.study
@pytest.mark.slow
def test_batch_pose_nees_inside_95_percent_bounds_on_shortened_aghili_rover():
    """20 seeds of a 4 s sim:aghili-rover with 3 anchors: the averaged pose NEES of the
    batch smoother's keyframes lies inside the two-sided 95 % chi-square bounds for at
    least 80 % of the keyframes."""
    runs = []
    for seed in range(1, 21):
        sequence = load_dataset("sim:aghili-rover", seed, {"duration_s": "4"})
        _, estimate = _run(SmootherBatch, SmootherBatch.Config(anchors=3), sequence)
        _, errors, valid = pose_error_series(estimate.smoothed.pose, sequence.ground_truth)
        runs.append(nees(errors, estimate.smoothed.pose.covariances[valid]))
    result = averaged_nees(np.array(runs), dof=6)
    assert result.inside_fraction >= 0.8, (result.inside_fraction, float(np.mean(result.mean)))


def test_batch_started_from_the_incremental_pass_is_not_worse_than_from_dead_reckoning():
    """Victoria Park (first 800 steps): LM from dead reckoning needs many iterations and
    ends at a higher (or equal) graph error than LM from the incremental solution, which
    starts next to its optimum (the file's own odometry noise, on which this was measured)."""
    sequence = load_dataset("victoria-park", 0, {"max_steps": "800", "odometry_noise": "file"})
    errors = {}
    for guess in ("incremental", "dead-reckoning"):
        estimator, estimate = _run(
            SmootherBatch, SmootherBatch.Config(initial_guess=guess), sequence
        )
        extras = estimate.diagnostics.extras
        errors[guess] = (
            float(extras["batch_error_start"][0]),
            float(extras["batch_error_final"][0]),
            int(extras["batch_iterations"][0]),
        )
    incremental, dead_reckoning = errors["incremental"], errors["dead-reckoning"]
    assert (
        incremental[0] < 1.01 * incremental[1] + 1.0
    )  # the incremental pass is already at the optimum
    assert dead_reckoning[0] > 100 * incremental[1]  # dead reckoning starts far away
    assert incremental[1] <= dead_reckoning[1] * (1 + 1e-6)
    assert incremental[2] <= dead_reckoning[2]
