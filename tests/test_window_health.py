"""A fixed-lag window that stops fitting its own new factors is divergence
(``smoothers.window_health``), reported with the time it began (``workbench.metrics.divergence``)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from datasets.estimate import EstimateRecorder
from datasets.sequence import NoiseSpec, Sequence
from smoothers.window_health import (
    UNSETTLED_CHI2_PER_DOF,
    UNSETTLED_UPDATES,
    UNSETTLED_WINDOW_S,
    WindowHealth,
    new_factor_chi2_per_dof,
)
from workbench.metrics.divergence import detect_divergence


def test_the_statistic_is_the_whitened_squared_residual_per_dof() -> None:
    graph = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Isotropic.Sigma(3, 0.5)
    graph.add(gtsam.PriorFactorPose2(1, gtsam.Pose2(0.0, 0.0, 0.0), noise))
    graph.add(gtsam.PriorFactorPose2(2, gtsam.Pose2(0.0, 0.0, 0.0), noise))  # not in values
    values = gtsam.Values()
    values.insert(1, gtsam.Pose2(1.0, 0.0, 0.0))  # 2 sigma along x
    assert np.isclose(new_factor_chi2_per_dof(graph, values), 2.0**2 / 3)
    assert new_factor_chi2_per_dof(gtsam.NonlinearFactorGraph(), values) is None


def test_one_large_correction_is_not_divergence_but_updates_that_do_not_settle_are() -> None:
    health = WindowHealth()
    big = 10 * UNSETTLED_CHI2_PER_DOF
    assert not health.check(100.0, big)  # a loop closure: iSAM2's look like this once
    for k in range(20):
        assert not health.check(101.0 + k, 1.0)
    assert health.diverged_at is None
    # unsettled updates further apart than the window never add up
    health = WindowHealth()
    for k in range(UNSETTLED_UPDATES + 2):
        assert not health.check(k * (UNSETTLED_WINDOW_S + 1.0), big)
    assert health.diverged_at is None
    # the same number within the window: divergence from the first of them, said once
    health = WindowHealth()
    found = [health.check(200.0 + k, big) for k in range(UNSETTLED_UPDATES + 2)]
    assert found == [False] * (UNSETTLED_UPDATES - 1) + [True, False, False]
    assert health.diverged_at == 200.0
    assert not health.check(300.0, None) and not health.check(301.0, UNSETTLED_CHI2_PER_DOF)


def test_a_window_divergence_event_is_the_divergence_time() -> None:
    recorder = EstimateRecorder(2)
    for t in np.arange(0.0, 60.0, 1.0):
        recorder.pose(t, np.zeros(2), 0.0, np.eye(3) * 0.01)
    recorder.event(12.0, "window_diverged", reason="3 updates within 30 s ...")
    recorder.event(40.0, "solver_failed", reason="GTSAM: indeterminate")
    sequence = Sequence(
        name="test",
        dimension=2,
        sensors=frozenset(),
        stream=lambda: iter(()),
        noise=NoiseSpec(landmark_range_m=5.0),
    )
    divergence = detect_divergence(recorder.build(), sequence)
    assert divergence is not None and divergence.t == 12.0
    assert "window stopped fitting" in divergence.reason


@pytest.mark.study
def test_the_intel_loop_closure_is_flagged_where_the_fixed_lag_window_diverges() -> None:
    """The Intel log's first loop closure (t = 976053085.54 s) turns the heading by 23.9 deg;
    iSAM2 settles it, the fixed-lag window does not (``smoothers.window_health``): flagged
    there, not 826 s later when GTSAM fails; iSAM2 on the same scans is not flagged."""
    from tests.test_carmen_logs import log_path
    from workbench.registry import load_dataset
    from workbench.runner import RunRequest, execute

    dataset = f"carmen:{log_path('intel')}"
    options = (("max_scans", "1300"),)
    sequence = load_dataset(dataset, 0, dict(options))
    found = {}
    for name in ("smoother-fixed-lag", "smoother-isam2"):
        result = execute(RunRequest(name, dataset, data_options=options), sequence=sequence)
        found[name] = detect_divergence(result.estimate, sequence)
    assert found["smoother-fixed-lag"] is not None
    assert abs(found["smoother-fixed-lag"].t - 976053085.54) < 0.5
    assert "window stopped fitting" in found["smoother-fixed-lag"].reason
    assert found["smoother-isam2"] is None
