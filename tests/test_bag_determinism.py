"""``workbench bag`` with its defaults is deterministic: KISS-ICP runs on one thread unless
``--threads`` says otherwise (with all cores, two runs differed at 1e-13..2e-9), and the
front end's metrics.json records the thread count."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from datasets.synthetic_lidar import write_lidar_bag
from workbench.cli import main


def _is_timing(key: str) -> bool:
    """Wall-clock figures, which no two runs share: ``time_*`` (README), ``*_ms_*`` and
    ``frames_per_s`` of the front end, ``*_seconds`` arrays of estimate.npz."""
    return key.startswith("time_") or "_ms_" in key or key.endswith(("_per_s", "_seconds"))


def _without_timing(metrics: dict) -> dict:
    return {key: value for key, value in metrics.items() if not _is_timing(key)}


def test_two_bag_runs_with_defaults_are_identical(tmp_path: Path, capsys) -> None:
    bag = write_lidar_bag(tmp_path / "corridor", 4, "ros1", {"duration_s": "0.6", "columns": "256"})
    outs = [tmp_path / "first", tmp_path / "second"]
    for out in outs:
        argv = ["bag", str(bag), "--out", str(out), "--estimator", "ekf-slam", "--no-plots"]
        assert main([*argv, "--truth-topic", "/ground_truth"]) == 0, capsys.readouterr().err
    fronts = [json.loads((out / "frontend" / "metrics.json").read_text()) for out in outs]
    assert fronts[0]["kiss_icp_threads"] == 1  # the default, recorded
    assert fronts[0]["frames"] > 3 and fronts[0]["kiss_icp_ate_rmse_m"] is not None
    assert _without_timing(fronts[0]) == _without_timing(fronts[1])
    runs = [json.loads((out / "ekf-slam" / "metrics.json").read_text()) for out in outs]
    assert runs[0]["ate_rmse_m"] is not None
    assert _without_timing(runs[0]) == _without_timing(runs[1])
    estimates = [np.load(out / "ekf-slam" / "estimate.npz") for out in outs]
    assert estimates[0].files == estimates[1].files and "pose_positions" in estimates[0].files
    for name in estimates[0].files:
        if not _is_timing(name):
            first, second = estimates[0][name], estimates[1][name]
            assert np.array_equal(first, second, equal_nan=first.dtype.kind == "f"), name
    tums = [(out / "frontend" / "kiss_icp.tum").read_bytes() for out in outs]
    assert tums[0] == tums[1]
