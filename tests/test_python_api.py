"""The Python API (``from workbench import run, compare, load_runs``) and the example that
uses it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from datasets.errors import InputError

REPO = Path(__file__).resolve().parents[1]


def test_run_compare_and_load_runs(tmp_path: Path) -> None:
    from workbench import compare, load_runs, run

    first = run(
        "ekf-slam",
        "sim:circle",
        seed=2,
        options={"velocity_walk_m_s_sqrt_s": [0.3, 0.3, 0.3], "gate_probability": 0.99},
        data={"duration_s": 2},
        out=tmp_path / "ekf",
    )
    assert first.folder == tmp_path / "ekf" and (first.folder / "metrics.json").is_file()
    assert first.metrics["ate_rmse_m"] > 0 and first.config.gate_probability == 0.99
    second = run("dead-reckoning", "sim:circle", seed=2, data={"duration_s": 2})
    assert second.folder is None and second.metrics["ate_rmse_m"] > first.metrics["ate_rmse_m"]
    table = compare([tmp_path])
    assert set(table["estimator"]) == {"ekf-slam"} and "anees_pose_per_dof" in table.columns
    runs = load_runs([tmp_path])
    assert list(runs["estimator"]) == ["ekf-slam"] and runs["seed"].iloc[0] == 2
    with pytest.raises(InputError, match="gate_probability"):
        run("ekf-slam", "sim:circle", options={"gate_probability": 3}, data={"duration_s": 1})


@pytest.mark.study
def test_the_example_compares_a_filter_and_a_smoother_and_draws_a_figure(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, str(REPO / "examples" / "compare_filter_and_smoother.py"), str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    assert "ekf-slam" in completed.stdout and "smoother-isam2" in completed.stdout
    assert (tmp_path / "position_error.png").stat().st_size > 10_000
