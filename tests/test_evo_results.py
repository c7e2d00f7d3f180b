"""evo interop of run folders: the APE/RPE result files load with evo's own loader and
``evo_res`` compares two runs with the figures metrics.json states; KITTI poses beside TUM."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main

evo_interface = pytest.importorskip("evo.tools.file_interface", reason="evo is a test extra")


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("evo")
    folders = (root / "smoother", root / "filter")
    for estimator, folder in zip(("smoother-isam2", "ekf-slam"), folders, strict=True):
        argv = ["run", estimator, "sim:circle", "--data", "duration_s=3", "--no-plots"]
        assert main([*argv, "--out", str(folder)]) == 0
    return folders


def test_result_files_load_in_evo_with_the_metrics_figures(two_runs) -> None:
    for folder in two_runs:
        metrics = json.loads((folder / "metrics.json").read_text())
        ape = evo_interface.load_res_file(folder / "ape.zip")
        rpe = evo_interface.load_res_file(folder / "rpe.zip")
        assert ape.stats["rmse"] == pytest.approx(metrics["ate_rmse_m"], rel=1e-12)
        assert rpe.stats["rmse"] == pytest.approx(metrics["rpe_trans_rmse_m"], rel=1e-12)
        assert len(ape.np_arrays["error_array"]) == len(ape.np_arrays["timestamps"])
    smoothed = evo_interface.load_res_file(two_runs[0] / "ape_smoothed.zip")
    metrics = json.loads((two_runs[0] / "metrics.json").read_text())
    assert smoothed.stats["rmse"] == pytest.approx(metrics["ate_rmse_smoothed_m"], rel=1e-12)


def test_evo_res_compares_two_run_folders(two_runs, tmp_path: Path) -> None:
    # evo's console script sits beside this interpreter in the virtual environment
    beside = Path(sys.executable).parent / "evo_res"
    command = str(beside) if beside.exists() else shutil.which("evo_res")
    assert command is not None, "evo_res (the test extra evo) is not installed"
    table = tmp_path / "table.csv"
    subprocess.run(
        [command, *(str(f / "ape.zip") for f in two_runs), "--save_table", str(table)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    rows = {row[""]: row for row in csv.DictReader(table.open())}
    for folder, estimator in zip(two_runs, ("smoother-isam2", "ekf-slam"), strict=True):
        metrics = json.loads((folder / "metrics.json").read_text())
        row = rows[f"{estimator} on sim:circle seed 0"]
        assert float(row["rmse"]) == pytest.approx(metrics["ate_rmse_m"], rel=1e-12)


def test_kitti_poses_beside_tum(two_runs) -> None:
    folder = two_runs[1]
    kitti = evo_interface.read_kitti_poses_file(folder / "estimate.kitti")
    tum = evo_interface.read_tum_trajectory_file(folder / "estimate.tum")
    np.testing.assert_allclose(kitti.positions_xyz, tum.positions_xyz, atol=1e-9)
