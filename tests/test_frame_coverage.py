"""Every frame has a pose, or the run says which do not (issue 37): ``Estimate.frame_times``
(landmark scans, sensor frames' increments) against the scored history's poses."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from datasets.estimate import EstimateRecorder
from workbench.metrics.summary import frame_metrics
from workbench.run_folder import frames_warning

CLIPS = [Path(__file__).resolve().parents[2] / "shared" / "data" / name for name in (
    "kitti-hdl64-clip", "kitti-hdl64-clip-b")]  # fmt: skip


def test_frames_without_a_pose_are_counted_and_said() -> None:
    recorder = EstimateRecorder(2)
    for t in (0.0, 0.1, 0.4, 0.5):
        recorder.pose(t, np.zeros(2), 0.0, None)
    estimate = replace(recorder.build(), frame_times=np.array([0.1, 0.2, 0.3, 0.4, 0.5005]))
    metrics = frame_metrics(estimate)
    assert (metrics["frames"], metrics["frames_without_pose"]) == (5, 2)
    assert metrics["frames_without_pose_t"] == [0.2, 0.3]
    (line,) = frames_warning(metrics, "smoother-isam2", "scans:x")
    assert "2 of 5 frames" in line and "0.20, 0.30" in line
    assert frames_warning(frame_metrics(replace(estimate, frame_times=None)), "e", "d") == []


@pytest.mark.study
@pytest.mark.parametrize("clip", CLIPS, ids=[clip.name for clip in CLIPS])
def test_every_estimator_has_a_pose_at_every_sweep_of_the_real_clips(clip: Path) -> None:
    if not clip.is_dir():
        pytest.skip(f"{clip} (real lidar data) absent")
    from workbench.registry import ESTIMATORS, load_dataset
    from workbench.runner import RunRequest, execute, is_compatible

    dataset = f"scans:{clip}"
    sequence = load_dataset(dataset, 0, {"kiss.max_num_threads": "1"})
    ran = 0
    for entry in ESTIMATORS:
        if not is_compatible(entry.load(), sequence):
            continue
        metrics = frame_metrics(
            execute(RunRequest(entry.name, dataset), sequence=sequence).estimate
        )
        assert metrics["frames"] >= len(list(clip.glob("*.pcd"))) - 2, entry.name
        assert metrics["frames_without_pose"] == 0, (entry.name, metrics["frames_without_pose_t"])
        ran += 1
    assert ran >= 6
