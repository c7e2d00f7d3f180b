"""The three shared CARMEN logs (Intel, Freiburg 079, MIT CSAIL) load with the defaults, and an
estimator runs on a slice of one with a pose at every scan; skipped where the logs are absent."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.measurements import LandmarkScan, Odometry, Sensor
from tests.conftest import SHARED_DATA

LOGS = SHARED_DATA / "carmen-logs"


def log_path(name: str):
    path = LOGS / f"{name}.clf.bz2"
    if not path.is_file():
        pytest.skip(f"CARMEN log {path.name} not found in {LOGS} (../shared/data beside the clone)")
    return path


@pytest.mark.parametrize(
    ("name", "scans", "reread"),
    [("intel", 13630, True), ("fr079", 4934, False), ("mit-csail", 1988, False)],
)
def test_each_shared_log_loads_with_the_defaults(name, scans, reread) -> None:
    from workbench.registry import load_dataset

    sequence = load_dataset(f"carmen:{log_path(name)}", 0, {})
    assert sequence.dimension == 2 and sequence.ground_truth is None
    assert sequence.sensors == frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS})
    assert sequence.metadata["totals"]["scans_used"] == scans
    counts = sequence.counts
    # the Intel log's unpadded microseconds are re-read, not dropped (one scan line is)
    assert (counts["scan_stamps_reread"] > 1000) is reread
    assert counts["scan_lines_dropped_out_of_order"] <= 1
    assert any(line.startswith("odometry:") for line in sequence.all_warnings())
    stream = sequence.measurements()
    first = [next(stream) for _ in range(40)]
    increments = [m for m in first if isinstance(m, Odometry)]
    assert all(m.frame and m.relative_pose.shape == (3,) for m in increments)
    assert all(m.ids is None for m in first if isinstance(m, LandmarkScan))
    times = [m.t for m in first]
    assert np.all(np.diff(times) >= 0) and times[0] > sequence.initial_state.t


def test_an_estimator_has_a_pose_at_every_scan_of_a_log_slice() -> None:
    """ekf-slam on MIT CSAIL's first 200 scans: a pose at each of the 199 frames, corners
    mapped without ids."""
    from workbench.metrics.summary import compute_metrics
    from workbench.runner import RunRequest, execute

    dataset = f"carmen:{log_path('mit-csail')}"
    result = execute(RunRequest("ekf-slam", dataset, data_options=(("max_scans", "200"),)))
    metrics = compute_metrics(result.estimate, result.sequence)
    assert metrics["frames"] == 199 and metrics["frames_without_pose"] == 0
    assert metrics["landmarks_in_map"] > 0
    pose = result.estimate.causal.pose
    assert np.all(np.isfinite(pose.positions)) and pose.t[-1] == pytest.approx(
        result.sequence.metadata["span_s"] + pose.t[0]
    )
