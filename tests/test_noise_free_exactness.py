"""On exact data every estimator's error is negligible against the covariance it states.

``noise_scale=0`` draws no noise but keeps the stated noise model, so what error remains is
the estimator's own: its integration scheme and linearisation, or a wrong convention. Its
NEES must then be a small fraction of the block's dof. This is the check that catches a
first-order integration rule hiding inside a consistent-looking Monte Carlo: GTSAM applies
a step's specific force at the step's start attitude, and on this scenario (10 s of the
20 Hz rover) that alone read 0.02-0.09 in every smoother block (smoothed gyro bias 0.086)
before ``smoothers.imu_graph.specific_force_at_step_start``; 0.0000 after. The loop with
wheel odometry (``odometry=true``) checks the estimators' odometry mode the same way (every
block 0.0000 there but the sensor-based velocity, 0.0035).
"""

from __future__ import annotations

import pytest

from workbench.metrics.summary import compute_metrics
from workbench.registry import ESTIMATORS, estimator_entry, load_dataset
from workbench.runner import is_compatible, resolve_config, run_estimator

SCENARIOS = {
    "sim:aghili-rover": {"duration_s": "10", "noise_scale": "0"},
    # the estimators' odometry mode: model-matched relative-pose odometry on the loop
    "sim:guerreiro-loop": {"duration_s": "20", "noise_scale": "0", "odometry": "true"},
}

EXACT_LIMIT = 0.002
"""Largest NEES per dof of exact data (0.01 for a whole 6-dof block); the old start-attitude
rule read 0.017-0.086 per block here (0.003-0.014 per dof)."""

MOTION_LIMITS = {("sensor-based", "velocity"): 0.05}
"""Blocks whose error on exact data is the true motion the model treats as process noise:
the sensor-based filter's body velocity is a random walk that only landmarks observe, and
the rover's speed changes in its turns (0.044 measured for the 2-dof block, 0.022 per dof)."""


def _cases() -> list:
    cases = []
    for dataset, options in SCENARIOS.items():
        sequence = load_dataset(dataset, 0, options)
        cases += [
            pytest.param(
                dataset,
                entry.name,
                id=f"{dataset}-{entry.name}",
                # the slowest (GTSAM's window over the 3-D rover): a study
                marks=[pytest.mark.study]
                if (dataset, entry.name) == ("sim:aghili-rover", "smoother-fixed-lag")
                else [],
            )
            for entry in ESTIMATORS
            if is_compatible(entry.load(), sequence)
        ]
    return cases


@pytest.mark.parametrize(("dataset", "estimator"), _cases())
def test_exact_data_leave_no_error_the_estimator_does_not_state(
    dataset: str, estimator: str
) -> None:
    estimator_class = estimator_entry(estimator).load()
    sequence = load_dataset(dataset, 0, SCENARIOS[dataset])
    estimate = run_estimator(estimator_class, resolve_config(estimator_class), sequence)
    metrics = compute_metrics(estimate, sequence)
    cells = {
        key.removeprefix("nees_").replace("_per_dof", ""): value
        for key, value in metrics.items()
        if key.startswith("nees_") and "_per_dof" in key and value is not None
    }
    assert cells, f"{estimator}: no NEES on {dataset}"
    for block, value in cells.items():
        limit = MOTION_LIMITS.get((estimator, block.removesuffix("_smoothed")), EXACT_LIMIT)
        assert value < limit, f"{estimator}: {block} NEES {value:.4f} on exact {dataset}"
